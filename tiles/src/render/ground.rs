//! The ground under a generated map: a land cover made up from the position alone (fields of
//! hashed colours separated by hedges, woods where a smooth noise is high), so that neighbouring
//! tiles and zoom levels join without seams. It shows a map is there and gives the eye a scale;
//! it is not the real ground.

/// Field sizes (m): across and along the furrows.
const FIELD_M: (f64, f64) = (170.0, 115.0);
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

/// The ground's colour at `(u, v)` (metres east and north on a plane of the world's scale)
/// when a pixel covers `m_per_px` metres.
pub(super) fn colour(u: f64, v: f64, m_per_px: f64) -> [u8; 3] {
    let wood = 0.65 * noise(u, v, WOOD_SCALES_M.0, 1) + 0.35 * noise(u, v, WOOD_SCALES_M.1, 2);
    if wood > WOOD_LEVEL {
        // Darker towards the middle of a wood.
        let shade = ((wood - WOOD_LEVEL) * 40.0).min(8.0) as u8;
        return WOOD.map(|c| c.saturating_sub(shade));
    }
    // Rows of fields, each row shifted by its own amount so the hedges do not line up.
    let row = (v / FIELD_M.1).floor();
    let shift = unit(hash(0, row as i64, 3)) * FIELD_M.0;
    let col = ((u + shift) / FIELD_M.0).floor();
    // Hedges a pixel wide (at least 3 m), only once fields are several pixels across.
    let hedge_m = (1.2 * m_per_px).max(3.0);
    if m_per_px < FIELD_M.1 / 8.0 {
        let du = (u + shift) - col * FIELD_M.0;
        let dv = v - row * FIELD_M.1;
        if du < hedge_m || dv < hedge_m {
            return HEDGE;
        }
    }
    FIELDS[(hash(col as i64, row as i64, 4) % FIELDS.len() as u64) as usize]
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
                let c = colour(u, v, 1.0);
                assert_eq!(c, colour(u, v, 1.0));
                woods += usize::from(c[0] <= WOOD[0]);
                kinds.insert(c);
            }
        }
        assert!((2_000..30_000).contains(&woods), "{woods} of 40 000 in woods");
        assert!(kinds.len() >= FIELDS.len(), "{kinds:?}");
        let n = noise(123.4, -567.8, 50.0, 9);
        assert!((0.0..1.0).contains(&n));
    }
}
