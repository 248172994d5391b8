//! The ground under a generated map: a land cover made up from the position alone (fields of
//! hashed colours separated by hedges, woods where a smooth noise is high), so that neighbouring
//! tiles and zoom levels join without seams. It shows a map is there and gives the eye a scale;
//! it is not the real ground.

/// Field sizes (m): the shortest width, how much wider a row's fields may be, the rows' depth.
const FIELD_M: (f64, f64, f64) = (90.0, 180.0, 115.0);
/// Wavelengths of the noise that decides where the woods are (m).
const WOOD_SCALES_M: (f64, f64) = (900.0, 260.0);
/// Noise above which the ground is wood.
const WOOD_LEVEL: f64 = 0.63;

/// Field colours: muted greens and browns, dark enough that the live picture (light glyphs and
/// labels) stays legible on top.
const FIELDS: [[u8; 3]; 6] = [
    [61, 78, 52],
    [74, 82, 56],
    [68, 72, 50],
    [55, 70, 54],
    [80, 76, 58],
    [64, 84, 60],
];
const WOOD: [u8; 3] = [38, 56, 40];
const HEDGE: [u8; 3] = [44, 58, 42];

/// A 64-bit mix of two integers and a salt (SplitMix64's finaliser).
fn hash(x: i64, y: i64, salt: u64) -> u64 {
    let mut z = (x as u64)
        .wrapping_mul(0x9e37_79b9_7f4a_7c15)
        .wrapping_add((y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f))
        .wrapping_add(salt);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A hash as a number in [0, 1).
fn unit(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Value noise in [0, 1) of wavelength `cell` (m): hashed lattice values, smoothly
/// interpolated.
fn noise(u: f64, v: f64, cell: f64, salt: u64) -> f64 {
    let (fu, fv) = (u / cell, v / cell);
    let (iu, iv) = (fu.floor(), fv.floor());
    let (tu, tv) = (fu - iu, fv - iv);
    let (su, sv) = (tu * tu * (3.0 - 2.0 * tu), tv * tv * (3.0 - 2.0 * tv));
    let (i, j) = (iu as i64, iv as i64);
    let at = |di, dj| unit(hash(i + di, j + dj, salt));
    let top = at(0, 0) + (at(1, 0) - at(0, 0)) * su;
    let bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * su;
    top + (bottom - top) * sv
}

/// The noise that makes woods at `(u, v)`: smooth over [`WOOD_SPACING_M`], so that a renderer
/// may sample it that far apart and interpolate.
pub(super) fn wood(u: f64, v: f64) -> f64 {
    0.65 * noise(u, v, WOOD_SCALES_M.0, 1) + 0.35 * noise(u, v, WOOD_SCALES_M.1, 2)
}

/// How far apart [`wood`] may be sampled (m): a tenth of its shortest wavelength.
pub(super) const WOOD_SPACING_M: f64 = WOOD_SCALES_M.1 / 10.0;

/// One row of fields: the ground along a line of constant `v` (metres north on a plane of the
/// world's scale) when a pixel covers `m_per_px` metres. Each row of fields has its own field
/// width and shift, so that nothing lines up.
#[derive(Debug, Clone, Copy)]
pub(super) struct Row {
    row: i64,
    width: f64,
    shift: f64,
    /// Hedges are drawn (fields are several pixels across), this wide (m).
    hedge_m: Option<f64>,
    /// On the hedge between two rows of fields.
    on_hedge: bool,
}

impl Row {
    pub(super) fn new(v: f64, m_per_px: f64) -> Self {
        let row = (v / FIELD_M.2).floor();
        let width = FIELD_M.0 + FIELD_M.1 * unit(hash(1, row as i64, 3));
        // Hedges a pixel wide (at least 3 m), only once fields are several pixels across.
        let hedge_m = (m_per_px < FIELD_M.2 / 8.0).then_some((1.2 * m_per_px).max(3.0));
        Self {
            row: row as i64,
            width,
            shift: unit(hash(0, row as i64, 3)) * width,
            on_hedge: hedge_m.is_some_and(|h| v - row * FIELD_M.2 < h),
            hedge_m,
        }
    }

    /// The ground's colour at `u` (metres east), `wood` being [`wood`] there.
    pub(super) fn colour(&self, u: f64, wood: f64) -> [u8; 3] {
        if wood > WOOD_LEVEL {
            // Darker towards the middle of a wood, in a few steps (flat areas keep PNGs small).
            let shade = ((wood - WOOD_LEVEL) * 40.0).min(8.0) as u8;
            return WOOD.map(|c| c.saturating_sub(shade));
        }
        let col = ((u + self.shift) / self.width).floor();
        if let Some(h) = self.hedge_m
            && (self.on_hedge || (u + self.shift) - col * self.width < h)
        {
            return HEDGE;
        }
        FIELDS[(hash(col as i64, self.row, 4) % FIELDS.len() as u64) as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ground_depends_on_the_place_only_and_has_fields_and_woods() {
        let mut woods = 0;
        let mut kinds = std::collections::HashSet::new();
        for i in 0..200 {
            for j in 0..200 {
                let (u, v) = (f64::from(i) * 37.0, f64::from(j) * 29.0);
                let c = Row::new(v, 1.0).colour(u, wood(u, v));
                assert_eq!(c, Row::new(v, 1.0).colour(u, wood(u, v)));
                woods += usize::from(c[0] <= WOOD[0]);
                kinds.insert(c);
            }
        }
        assert!(
            (2_000..30_000).contains(&woods),
            "{woods} of 40 000 in woods"
        );
        assert!(kinds.len() >= FIELDS.len(), "{kinds:?}");
        let n = noise(123.4, -567.8, 50.0, 9);
        assert!((0.0..1.0).contains(&n));
    }
}
