//! What an experiment measured: every measurement with its configuration and timing, and the
//! summaries drawn from them (means over repetitions, log-log slopes). Serialised as
//! `results.json`.

use std::collections::BTreeMap;

use pathlight_render::config::CameraConfig;
use serde::{Deserialize, Serialize};

use crate::metrics::Metric;
use crate::reference::ReferenceInfo;
use crate::spec::Spec;

/// The point of a budget at which an image was measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BudgetPoint {
    /// Every pixel had this many samples.
    Spp(u32),
    /// This much render time (milliseconds) had passed.
    TimeMs(f64),
}

/// One image of one configuration, measured against its view's reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    pub configuration: String,
    pub repetition: u32,
    pub seed: u64,
    /// Index of the view along the camera path.
    pub view: usize,
    pub budget: BudgetPoint,
    /// Mean samples per pixel in the image.
    pub spp: f64,
    /// Render time of the image at its view, in milliseconds (metrics excluded).
    pub ms: f64,
    /// Milliseconds per stage of the pipeline (they sum to `ms`).
    pub stages: BTreeMap<String, f64>,
    pub metrics: BTreeMap<Metric, f64>,
}

/// A reference and the view it belongs to.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ViewReference {
    pub view: usize,
    #[serde(flatten)]
    pub info: ReferenceInfo,
}

/// The least-squares slope of log(error) against log(spp) or log(ms).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Slope {
    pub configuration: String,
    pub metric: Metric,
    /// "spp" or "ms".
    pub against: String,
    pub slope: f64,
    /// Budget points in the fit.
    pub points: usize,
}

/// Everything `results.json` holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Results {
    pub spec: Spec,
    pub renderer: String,
    pub threads: usize,
    /// False when the run was stopped (Ctrl-C) before every measurement was taken.
    pub complete: bool,
    pub views: Vec<CameraConfig>,
    pub references: Vec<ViewReference>,
    pub measurements: Vec<Measurement>,
    /// Log-log slopes of the lower-is-better metrics, from the equal-samples budgets.
    pub slopes: Vec<Slope>,
}

/// Mean over repetitions and measured views of one configuration's metric at each budget
/// point: (mean spp, mean ms, mean value), in budget order.
pub fn mean_by_budget(
    measurements: &[Measurement],
    configuration: &str,
    metric: Metric,
    time_budgets: bool,
) -> Vec<(f64, f64, f64)> {
    let mut groups: Vec<(BudgetPoint, [f64; 3], usize)> = Vec::new();
    for m in measurements.iter().filter(|m| {
        m.configuration == configuration
            && matches!(m.budget, BudgetPoint::TimeMs(_)) == time_budgets
    }) {
        let Some(&v) = m.metrics.get(&metric) else {
            continue;
        };
        let i = match groups.iter().position(|g| g.0 == m.budget) {
            Some(i) => i,
            None => {
                groups.push((m.budget, [0.0; 3], 0));
                groups.len() - 1
            }
        };
        let g = &mut groups[i];
        g.1[0] += m.spp;
        g.1[1] += m.ms;
        g.1[2] += v;
        g.2 += 1;
    }
    groups
        .into_iter()
        .map(|(_, s, n)| (s[0] / n as f64, s[1] / n as f64, s[2] / n as f64))
        .collect()
}

/// Least-squares slope of log y against log x over the points where both are positive and
/// finite; `None` with fewer than two such points or no spread in x.
pub fn log_log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The slopes of every configuration and lower-is-better metric against spp and against ms.
pub fn slopes(spec: &Spec, measurements: &[Measurement]) -> Vec<Slope> {
    let mut out = Vec::new();
    for c in &spec.configurations {
        for &metric in spec.metrics.iter().filter(|m| m.lower_is_better()) {
            let means = mean_by_budget(measurements, &c.name, metric, false);
            for (against, pick) in [("spp", 0usize), ("ms", 1)] {
                let points: Vec<(f64, f64)> = means
                    .iter()
                    .map(|p| (if pick == 0 { p.0 } else { p.1 }, p.2))
                    .collect();
                if let Some(slope) = log_log_slope(&points) {
                    out.push(Slope {
                        configuration: c.name.clone(),
                        metric,
                        against: against.to_owned(),
                        slope,
                        points: points.len(),
                    });
                }
            }
        }
    }
    out
}

impl Results {
    /// The slope of `configuration`'s `metric` against `against` ("spp" or "ms").
    pub fn slope(&self, configuration: &str, metric: Metric, against: &str) -> Option<f64> {
        self.slopes
            .iter()
            .find(|s| {
                s.configuration == configuration && s.metric == metric && s.against == against
            })
            .map(|s| s.slope)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law_is_its_exponent() {
        let points: Vec<(f64, f64)> = [1.0, 4.0, 16.0, 64.0]
            .iter()
            .map(|&x: &f64| (x, 3.0 * x.powf(-1.25)))
            .collect();
        assert!((log_log_slope(&points).unwrap() + 1.25).abs() < 1e-12);
        // Non-positive and non-finite points are left out.
        let mut with_bad = points.clone();
        with_bad.push((0.0, 1.0));
        with_bad.push((8.0, f64::NAN));
        assert!((log_log_slope(&with_bad).unwrap() + 1.25).abs() < 1e-12);
        assert_eq!(log_log_slope(&points[..1]), None);
        assert_eq!(log_log_slope(&[(2.0, 1.0), (2.0, 3.0)]), None);
    }

    fn m(config: &str, rep: u32, spp: u32, v: f64) -> Measurement {
        Measurement {
            configuration: config.into(),
            repetition: rep,
            seed: rep as u64,
            view: 0,
            budget: BudgetPoint::Spp(spp),
            spp: spp as f64,
            ms: 10.0 * spp as f64,
            stages: BTreeMap::new(),
            metrics: [(Metric::Mse, v)].into_iter().collect(),
        }
    }

    #[test]
    fn means_are_taken_over_repetitions_per_budget() {
        let ms = vec![
            m("a", 0, 1, 1.0),
            m("a", 1, 1, 3.0),
            m("a", 0, 4, 0.5),
            m("b", 0, 1, 9.0),
        ];
        assert_eq!(
            mean_by_budget(&ms, "a", Metric::Mse, false),
            vec![(1.0, 10.0, 2.0), (4.0, 40.0, 0.5)]
        );
        assert!(mean_by_budget(&ms, "a", Metric::Mse, true).is_empty());
        assert!(mean_by_budget(&ms, "a", Metric::Ssim, false).is_empty());
    }
}
