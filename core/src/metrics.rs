//! Metrics with the definitions of `shared/scenarios/score.py`: RMSE, max error, NEES with χ²
//! bounds, ellipsoid containment and volume, one-step prediction error.
//!
//! [`score`] reproduces `score.py`'s summary for an estimate sequence; tests check that both agree.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector, Vector3};

use crate::linalg::wrap_angle;
use crate::measurement::MeasKind;
use crate::scenario::{Estimate, Measurement, Scenario, TruthRow, default_cov_dims, truth_at};

/// Root mean square of `v` (`None` when empty).
pub fn rms(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt())
}

/// Volume of the n-dimensional unit ball, `π^(n/2) / Γ(n/2 + 1)`.
pub fn unit_ball_volume(n: usize) -> f64 {
    // Γ(n/2 + 1) by recurrence from Γ(1) = 1 or Γ(1/2) = √π.
    let mut g = if n % 2 == 0 { 1.0 } else { PI.sqrt() };
    let mut a = if n % 2 == 0 { 1.0 } else { 0.5 };
    while a < n as f64 / 2.0 + 1.0 - 1e-9 {
        g *= a;
        a += 1.0;
    }
    PI.powf(n as f64 / 2.0) / g
}

/// ln Γ(x) (Lanczos, g = 7, 9 terms; |error| < 1e-13 for x > 0).
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised lower incomplete gamma `P(a, x)` (series for x < a + 1, continued fraction above;
/// Numerical Recipes §6.2).
fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let lnpre = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..500 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        sum * lnpre.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..500 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        1.0 - lnpre.exp() * h
    }
}

/// χ² cumulative distribution with `dof` degrees of freedom.
pub fn chi2_cdf(x: f64, dof: usize) -> f64 {
    gamma_p(dof as f64 / 2.0, x / 2.0)
}

/// χ² quantile: the x with `chi2_cdf(x, dof) = p` (bisection to 1e-12 relative).
pub fn chi2_quantile(p: f64, dof: usize) -> f64 {
    let (mut lo, mut hi) = (0.0, dof as f64 + 10.0 * (dof as f64).sqrt() + 100.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_cdf(mid, dof) < p {
            lo = mid
        } else {
            hi = mid
        }
        if hi - lo < 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// NEES statistics as `score.py` reports them.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NeesSummary {
    /// Degrees of freedom.
    pub dof: usize,
    /// Mean NEES.
    pub mean: f64,
    /// Mean NEES per degree of freedom (≈ 1 when consistent).
    pub mean_per_dof: f64,
    /// Fraction of epochs with NEES ≤ χ²₀.₉₅(dof).
    pub frac_within_95: f64,
    /// χ²₀.₉₅(dof).
    pub chi2_95_bound: f64,
    /// Number of epochs.
    pub n: usize,
}

/// One-step-ahead prediction errors of one measurement kind: `(vs truth, vs measurement)`, one
/// vector of components per epoch.
type PredictionErrors = (Vec<Vec<f64>>, Vec<Vec<f64>>);

fn nees_summary(v: &[f64], dof: usize) -> Option<NeesSummary> {
    if v.is_empty() || dof == 0 {
        return None;
    }
    let bound = chi2_quantile(0.95, dof);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    Some(NeesSummary {
        dof,
        mean,
        mean_per_dof: mean / dof as f64,
        frac_within_95: v.iter().filter(|x| **x <= bound).count() as f64 / v.len() as f64,
        chi2_95_bound: bound,
        n: v.len(),
    })
}

/// Ellipsoid containment and volume.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EllipsoidSummary {
    /// Canonical dims of the ellipsoid.
    pub dims: Vec<usize>,
    /// Fraction of epochs whose ellipsoid contains the truth (tolerance 1e-9).
    pub containment: f64,
    /// Number of epochs.
    pub n: usize,
    /// Epochs with the truth outside.
    pub violations: usize,
    /// Mean volume.
    pub mean_volume: f64,
    /// Median volume.
    pub median_volume: f64,
}

/// One-step prediction errors per component, for one measurement kind.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PredictionSummary {
    /// max |ẑ − h(truth)| per component.
    pub max_abs_vs_truth: Vec<f64>,
    /// RMS of ẑ − h(truth) per component.
    pub rms_vs_truth: Vec<f64>,
    /// max |ẑ − z| per component.
    pub max_abs_vs_meas: Vec<f64>,
    /// RMS of ẑ − z per component.
    pub rms_vs_meas: Vec<f64>,
    /// Number of predictions.
    pub n: usize,
}

/// The score of an estimate sequence (the fields of `score.py`'s JSON that Harrier uses).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct Score {
    /// Estimates at or after `t_start` within the truth's time range.
    pub scored: usize,
    /// Position RMSE over the scored dims (m).
    pub pos_rmse: Option<f64>,
    /// Velocity RMSE (m/s).
    pub vel_rmse: Option<f64>,
    /// Largest position error (m).
    pub pos_max: Option<f64>,
    /// Position RMSE per truth mode label.
    pub pos_rmse_by_mode: BTreeMap<String, f64>,
    /// NEES over all scored dims present in the covariance.
    pub nees: Option<NeesSummary>,
    /// NEES over the position dims.
    pub nees_pos: Option<NeesSummary>,
    /// Ellipsoid containment and volume.
    pub ellipsoid: Option<EllipsoidSummary>,
    /// One-step prediction errors by measurement kind.
    pub prediction: BTreeMap<String, PredictionSummary>,
}

/// Noise-free measurement of a target at `tgt` from a sensor at `plat` (`common.py::h_meas`).
pub fn h_meas(
    kind: MeasKind,
    tgt: &Vector3<f64>,
    plat: &Vector3<f64>,
    size: Option<f64>,
    ncomp: usize,
) -> Vec<f64> {
    let d = tgt - plat;
    let az = d.x.atan2(d.y);
    let el = d.z.atan2(d.x.hypot(d.y));
    match kind {
        MeasKind::Position => tgt.iter().take(ncomp).copied().collect(),
        MeasKind::RangeBearing => vec![d.norm(), az],
        MeasKind::AzEl => vec![az, el],
        MeasKind::BearingSize => {
            vec![
                az,
                el,
                size.map_or(f64::NAN, |s| 2.0 * (s / (2.0 * d.norm())).atan()),
            ]
        }
    }
}

fn nees(
    x: &[f64; 6],
    tru: &[f64; 6],
    cov: &[Vec<f64>],
    cov_dims: &[usize],
    want: &[usize],
) -> (f64, usize) {
    let dims: Vec<usize> = cov_dims
        .iter()
        .copied()
        .filter(|d| want.contains(d))
        .collect();
    if dims.is_empty() {
        return (0.0, 0);
    }
    let idx: Vec<usize> = dims
        .iter()
        .filter_map(|d| cov_dims.iter().position(|c| c == d))
        .collect();
    let n = dims.len();
    let p = DMatrix::from_fn(n, n, |i, j| {
        cov.get(idx[i])
            .and_then(|r| r.get(idx[j]))
            .copied()
            .unwrap_or(f64::NAN)
    });
    let e = DVector::from_fn(n, |i, _| x[dims[i]] - tru[dims[i]]);
    let v = p.lu().solve(&e).map_or(f64::INFINITY, |s| e.dot(&s));
    (v, n)
}

/// Scores `est` against `truth` exactly as `score.py` does (FORMAT.md §6). `true_size` is the
/// target size used for `bearing_size` predictions.
pub fn score(
    sc: &Scenario,
    meas: &[Measurement],
    truth: &[TruthRow],
    est: &[Estimate],
    true_size: Option<f64>,
) -> Score {
    let t_start = sc.scoring.t_start;
    let act = sc.active_dims();
    let pos: Vec<usize> = act.iter().copied().filter(|d| *d < 3).collect();
    let vel: Vec<usize> = act.iter().copied().filter(|d| *d >= 3).collect();
    let key = |t: f64| (t * 1e6).round() as i64;
    let meas_index: BTreeMap<(i64, &str), &Measurement> = meas
        .iter()
        .map(|m| ((key(m.t), m.sensor.as_str()), m))
        .collect();

    let mut out = Score::default();
    let (mut pos_err, mut vel_err) = (Vec::new(), Vec::new());
    let mut mode_err: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let (mut nf, mut np, mut dof_f, mut dof_p) = (Vec::new(), Vec::new(), 0, 0);
    let (mut contain, mut volumes, mut ell_dims) = (Vec::new(), Vec::new(), Vec::new());
    // Per kind: prediction errors against the noise-free truth and against the measurement.
    let mut pred: BTreeMap<MeasKind, PredictionErrors> = BTreeMap::new();

    for e in est {
        if e.t < t_start - 1e-9 {
            continue;
        }
        let Some((tru, mode, _)) = truth_at(truth, e.t) else {
            continue;
        };
        out.scored += 1;
        if let Some(x) = &e.state {
            let pe = pos
                .iter()
                .map(|&d| (x[d] - tru[d]).powi(2))
                .sum::<f64>()
                .sqrt();
            pos_err.push(pe);
            vel_err.push(
                vel.iter()
                    .map(|&d| (x[d] - tru[d]).powi(2))
                    .sum::<f64>()
                    .sqrt(),
            );
            if !mode.is_empty() {
                mode_err.entry(mode.to_string()).or_default().push(pe);
            }
            if let Some(cov) = &e.cov {
                let cd = e
                    .cov_dims
                    .clone()
                    .unwrap_or_else(|| default_cov_dims(cov.len()));
                let (v, d) = nees(x, &tru, cov, &cd, act);
                if d > 0 {
                    nf.push(v);
                    dof_f = d;
                }
                let (v, d) = nees(x, &tru, cov, &cd, &pos);
                if d > 0 {
                    np.push(v);
                    dof_p = d;
                }
            }
        }
        if let Some(ell) = &e.ellipsoid {
            let dims = ell
                .dims
                .clone()
                .unwrap_or_else(|| default_cov_dims(ell.center.len()));
            let n = dims.len();
            let s = DMatrix::from_fn(n, n, |i, j| {
                ell.shape
                    .get(i)
                    .and_then(|r| r.get(j))
                    .copied()
                    .unwrap_or(f64::NAN)
            });
            let r = DVector::from_fn(n, |i, _| {
                tru[dims[i]] - ell.center.get(i).copied().unwrap_or(f64::NAN)
            });
            let d2 = s
                .clone()
                .lu()
                .solve(&r)
                .map_or(f64::INFINITY, |v| r.dot(&v));
            contain.push(d2 <= 1.0 + 1e-9);
            volumes.push(unit_ball_volume(n) * s.determinant().max(0.0).sqrt());
            ell_dims = dims;
        }
        if let Some(p) = &e.prediction {
            let Some(m) = meas_index.get(&(key(p.t), p.sensor.as_str())) else {
                continue;
            };
            let Some((tn, _, _)) = truth_at(truth, p.t) else {
                continue;
            };
            let tgt = Vector3::new(tn[0], tn[1], tn[2]);
            let plat = Vector3::from(m.platform.pos);
            let zt = h_meas(m.kind, &tgt, &plat, true_size, m.z.len());
            let wrap = |i: usize, v: f64| {
                if Some(i) == m.kind.azimuth_index() {
                    wrap_angle(v)
                } else {
                    v
                }
            };
            let et: Vec<f64> =
                p.z.iter()
                    .zip(&zt)
                    .enumerate()
                    .map(|(i, (a, b))| wrap(i, a - b))
                    .collect();
            let em: Vec<f64> =
                p.z.iter()
                    .zip(&m.z)
                    .enumerate()
                    .map(|(i, (a, b))| wrap(i, a - b))
                    .collect();
            let entry = pred.entry(m.kind).or_default();
            entry.0.push(et);
            entry.1.push(em);
        }
    }
    out.pos_rmse = rms(&pos_err);
    out.vel_rmse = rms(&vel_err);
    out.pos_max = pos_err.iter().copied().reduce(f64::max);
    out.pos_rmse_by_mode = mode_err
        .iter()
        .filter_map(|(k, v)| Some((k.clone(), rms(v)?)))
        .collect();
    out.nees = nees_summary(&nf, dof_f);
    out.nees_pos = nees_summary(&np, dof_p);
    if !contain.is_empty() {
        let n = contain.len();
        let inside = contain.iter().filter(|c| **c).count();
        let mut sorted = volumes.clone();
        sorted.sort_by(f64::total_cmp);
        let median = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
        };
        out.ellipsoid = Some(EllipsoidSummary {
            dims: ell_dims,
            containment: inside as f64 / n as f64,
            n,
            violations: n - inside,
            mean_volume: volumes.iter().sum::<f64>() / n as f64,
            median_volume: median,
        });
    }
    for (kind, (et, em)) in pred {
        let k = et.first().map_or(0, Vec::len);
        let col = |v: &[Vec<f64>], i: usize| v.iter().map(|r| r[i]).collect::<Vec<_>>();
        let max_abs = |v: &[Vec<f64>]| {
            (0..k)
                .map(|i| col(v, i).iter().fold(0.0f64, |a, b| a.max(b.abs())))
                .collect()
        };
        let rmss = |v: &[Vec<f64>]| (0..k).map(|i| rms(&col(v, i)).unwrap_or(0.0)).collect();
        let name = serde_json::to_value(kind)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default();
        out.prediction.insert(
            name,
            PredictionSummary {
                max_abs_vs_truth: max_abs(&et),
                rms_vs_truth: rmss(&et),
                max_abs_vs_meas: max_abs(&em),
                rms_vs_meas: rmss(&em),
                n: et.len(),
            },
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn chi2_quantiles_match_tables() {
        // scipy.stats.chi2.ppf(0.95, k)
        for (k, q) in [
            (1, 3.841_458_820_694_124),
            (2, 5.991_464_547_107_979),
            (4, 9.487_729_036_781_154),
            (6, 12.591_587_243_743_977),
        ] {
            assert_relative_eq!(chi2_quantile(0.95, k), q, max_relative = 1e-9);
        }
    }

    #[test]
    fn unit_ball_volumes() {
        assert_relative_eq!(unit_ball_volume(1), 2.0);
        assert_relative_eq!(unit_ball_volume(2), PI);
        assert_relative_eq!(unit_ball_volume(3), 4.0 / 3.0 * PI);
        assert_relative_eq!(unit_ball_volume(4), PI * PI / 2.0);
    }
}
