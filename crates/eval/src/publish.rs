//! Writes an experiment's outcome to a folder: `results.json`, plots as PNG (error against
//! samples and against time with one line per configuration, equal-time error bars, time per
//! stage), the images next to the reference with crops and error maps, and `report.html`
//! showing all of it.

use std::path::{Path, PathBuf};

use pathlight_render::output::{encode_png, encode_rgba8_png, write_atomic};

use crate::experiment::Outcome;
use crate::metrics::{self, Metric};
use crate::plot::{self, Axis, Series, Stack};
use crate::report::{self, Figure, Report, Section, Table};
use crate::results::{mean_by_budget, BudgetPoint, Results};
use crate::EvalError;

const CHART: (u32, u32) = (900, 560);
/// Crops shown per image, their side in pixels and their upscaling.
const CROPS: usize = 3;
const CROP_FRACTION: f32 = 0.25;
const CROP_DISPLAY: u32 = 256;
/// Smallest display width of the full images.
const IMAGE_DISPLAY: u32 = 256;

/// Writes everything into `out` (created if missing) and returns the report's path.
pub fn publish(outcome: &Outcome, out: &Path) -> Result<PathBuf, EvalError> {
    let results = &outcome.results;
    for dir in [out.to_owned(), out.join("plots"), out.join("images")] {
        std::fs::create_dir_all(&dir).map_err(|e| EvalError::io(dir.clone(), e))?;
    }
    let json = serde_json::to_vec_pretty(results).expect("results serialise");
    write_atomic(&out.join("results.json"), &json)?;

    let spec = &results.spec;
    let mut report = Report {
        title: format!("pathlight eval: {}", spec.name),
        subtitle: spec.description.clone(),
        sections: vec![overview(results)],
    };
    let mut samples = section("Error against samples", "Mean over repetitions and measured views; log-log axes. Plain Monte Carlo falls as 1/spp (slope -1).");
    let mut time = section(
        "Error against time",
        "Every measured image (the equal-samples budgets and the equal-time ones) by render time, metric computation excluded; mean over repetitions and measured views.",
    );
    let mut equal = section("Equal budget", "Each configuration at the largest budget: equal time when the spec has time budgets, else equal samples.");
    for &metric in &spec.metrics {
        let name = metric.name();
        let y = Axis {
            label: metric.description().to_owned(),
            log: metric.lower_is_better(),
        };
        let mut by_spp = Vec::new();
        let mut by_ms = Vec::new();
        let mut bars = Vec::new();
        for c in &spec.configurations {
            let spp_points = mean_by_budget(&results.measurements, &c.name, metric, false);
            let time_points = mean_by_budget(&results.measurements, &c.name, metric, true);
            if !spp_points.is_empty() {
                by_spp.push(Series {
                    name: c.name.clone(),
                    points: spp_points.iter().map(|p| (p.0, p.2)).collect(),
                    guide: false,
                });
            }
            // Against time: every measured image, from the equal-samples runs and the
            // equal-time ones alike, in order of time.
            let mut by_time: Vec<(f64, f64)> = spp_points
                .iter()
                .chain(&time_points)
                .map(|p| (p.1, p.2))
                .collect();
            by_time.sort_by(|a, b| a.0.total_cmp(&b.0));
            by_ms.push(Series {
                name: c.name.clone(),
                points: by_time,
                guide: false,
            });
            let last = if time_points.is_empty() {
                spp_points.last()
            } else {
                time_points.last()
            };
            if let Some(p) = last {
                bars.push((c.name.clone(), p.2));
            }
        }
        if let Some(guide) = monte_carlo_guide(metric, &by_spp) {
            by_spp.push(guide);
        }
        if !by_spp.is_empty() {
            samples.figures.push(line_figure(
                out,
                &format!("plots/{name}-vs-spp.png"),
                &format!("{metric} against samples"),
                "samples per pixel",
                &y,
                &by_spp,
                &format!("{} against samples per pixel", metric.description()),
            )?);
        }
        time.figures.push(line_figure(
            out,
            &format!("plots/{name}-vs-time.png"),
            &format!("{metric} against time"),
            "render time (ms)",
            &y,
            &by_ms,
            &format!("{} against render time", metric.description()),
        )?);

        let budget = match (spec.budget.time_ms.last(), spec.budget.spp.last()) {
            (Some(t), _) => format!("equal time, {t} ms"),
            (None, Some(s)) => format!("equal samples, {s} spp"),
            (None, None) => String::new(),
        };
        let file = format!("plots/{name}-equal.png");
        let png = plot::bar_chart(&format!("{metric}, {budget}"), &y, &bars, CHART.0, CHART.1)?;
        write(out, &file, &png)?;
        equal.figures.push(figure(
            &file,
            &format!("{} at {budget}", metric.description()),
        ));
    }
    equal.tables.push(final_values(results));
    report
        .sections
        .extend([samples, time, equal, stages(results, out)?]);
    if let Some(s) = &outcome.snapshots {
        report.sections.push(images(results, s, out)?);
    }
    let path = out.join("report.html");
    report::write_html(&report, &path)?;
    Ok(path)
}

/// The plain Monte Carlo rate through the first series' first point: MSE-like metrics fall
/// as 1/spp (slope -1), RMSE as 1/sqrt(spp); none for the others.
fn monte_carlo_guide(metric: Metric, series: &[Series]) -> Option<Series> {
    let slope = match metric {
        Metric::Mse | Metric::Relmse | Metric::Luvmse => -1.0,
        Metric::Rmse => -0.5,
        _ => return None,
    };
    let (x0, y0) = *series.first()?.points.first()?;
    let x1 = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .fold(x0, f64::max);
    (x1 > x0).then(|| Series {
        name: format!("slope {slope} (plain Monte Carlo)"),
        points: [x0, x1]
            .iter()
            .map(|&x| (x, y0 * (x / x0).powf(slope)))
            .collect(),
        guide: true,
    })
}

fn section(title: &str, text: &str) -> Section {
    Section {
        title: title.to_owned(),
        text: text.to_owned(),
        ..Section::default()
    }
}

/// A chart, shown at the page's width.
/// A line chart of `series` over a logarithmic x axis labelled `x_label`, written to `file`
/// under `out`, as a figure captioned `caption`.
fn line_figure(
    out: &Path,
    file: &str,
    title: &str,
    x_label: &str,
    y: &Axis,
    series: &[Series],
    caption: &str,
) -> Result<Figure, EvalError> {
    let x = Axis {
        label: x_label.to_owned(),
        log: true,
    };
    let png = plot::line_chart(title, &x, y, series, CHART.0, CHART.1)?;
    write(out, file, &png)?;
    Ok(figure(file, caption))
}

fn figure(path: &str, caption: &str) -> Figure {
    Figure {
        path: path.to_owned(),
        caption: caption.to_owned(),
        display_width: None,
    }
}

/// An image shown `width` pixels wide, without smoothing.
fn picture(path: &str, caption: &str, width: u32) -> Figure {
    Figure {
        display_width: Some(width),
        ..figure(path, caption)
    }
}

fn write(out: &Path, file: &str, bytes: &[u8]) -> Result<(), EvalError> {
    Ok(write_atomic(&out.join(file), bytes)?)
}

/// A file-name-safe, unique form of the `index`th configuration's name.
fn slug(index: usize, name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    format!("{index}-{}", s.trim_matches('-'))
}

fn overview(results: &Results) -> Section {
    let spec = &results.spec;
    let mut s = section("Experiment", "");
    s.text = format!(
        "Scene: {}. {}x{} pixels, {} view(s) along a {:?} camera path, {} repetition(s), {} thread(s), renderer {}.{}",
        spec.scene
            .as_ref()
            .map_or("the built-in Cornell box".to_owned(), |p| p.display().to_string()),
        spec.width,
        spec.height,
        results.views.len(),
        spec.camera.path,
        spec.repetitions,
        results.threads,
        results.renderer,
        if results.complete {
            ""
        } else {
            " STOPPED before the end: the figures show what was measured."
        }
    );
    s.tables.push(Table {
        caption: "References (the reference path tracer; expected MSE is the reference's own noise, included in every measured MSE)".into(),
        headers: ["view", "spp", "render time", "expected MSE", "cache key"].map(String::from).to_vec(),
        rows: results
            .references
            .iter()
            .map(|r| {
                vec![
                    r.view.to_string(),
                    r.info.config.spp.to_string(),
                    if r.info.cached {
                        format!("cached ({:.1} s)", r.info.render_seconds)
                    } else {
                        format!("{:.1} s", r.info.render_seconds)
                    },
                    format!("{:.3e}", r.info.expected_mse),
                    r.info.key.clone(),
                ]
            })
            .collect(),
    });
    let default = serde_json::to_value(pathlight_render::Config::default()).expect("serialisable");
    s.tables.push(Table {
        caption: "Configurations (settings that differ from the defaults)".into(),
        headers: vec!["configuration".into(), "settings".into()],
        rows: spec
            .configurations
            .iter()
            .map(|c| {
                let v = serde_json::to_value(&c.config).expect("serialisable");
                let diff: Vec<String> = v
                    .as_object()
                    .into_iter()
                    .flatten()
                    .filter(|(k, val)| {
                        default.get(k.as_str()) != Some(val)
                            && !["width", "height", "spp"].contains(&k.as_str())
                    })
                    .map(|(k, val)| format!("{k} = {val}"))
                    .collect();
                vec![
                    c.name.clone(),
                    if diff.is_empty() {
                        "defaults".into()
                    } else {
                        diff.join(", ")
                    },
                ]
            })
            .collect(),
    });
    if !results.slopes.is_empty() {
        s.tables.push(Table {
            caption: "Log-log slopes of error against samples per pixel and against time (least squares over the budget points)".into(),
            headers: ["configuration", "metric", "against", "slope", "points"].map(String::from).to_vec(),
            rows: results
                .slopes
                .iter()
                .map(|l| vec![l.configuration.clone(), l.metric.to_string(), l.against.clone(), format!("{:.3}", l.slope), l.points.to_string()])
                .collect(),
        });
    }
    s
}

/// Configuration x metric at the last budget point (mean over repetitions and views).
fn final_values(results: &Results) -> Table {
    let spec = &results.spec;
    let mut headers = vec![
        "configuration".to_owned(),
        "budget".to_owned(),
        "spp".to_owned(),
        "ms".to_owned(),
    ];
    headers.extend(spec.metrics.iter().map(|m| m.to_string()));
    let mut rows = Vec::new();
    for c in &spec.configurations {
        for time in [false, true] {
            let mut row = Vec::new();
            for (i, &metric) in spec.metrics.iter().enumerate() {
                let Some(p) = mean_by_budget(&results.measurements, &c.name, metric, time)
                    .last()
                    .copied()
                else {
                    // (A temporal metric with a single view measured: none.)
                    if !row.is_empty() {
                        row.push("-".to_owned());
                    }
                    continue;
                };
                if i == 0 {
                    row = vec![
                        c.name.clone(),
                        if time { "time" } else { "samples" }.to_owned(),
                        format!("{:.1}", p.0),
                        format!("{:.1}", p.1),
                    ];
                }
                row.push(format!("{:.4e}", p.2));
            }
            if !row.is_empty() {
                rows.push(row);
            }
        }
    }
    Table {
        caption: "Error at each configuration's last budget point".into(),
        headers,
        rows,
    }
}

/// Time per stage, per sample per pixel, at the last equal-samples budget (or the last
/// equal-time one).
fn stages(results: &Results, out: &Path) -> Result<Section, EvalError> {
    let mut s = section(
        "Time per stage",
        "Milliseconds per sample per pixel of each stage of the pipeline, mean over repetitions.",
    );
    let mut stacks = Vec::new();
    for c in &results.spec.configurations {
        let last = results
            .measurements
            .iter()
            .filter(|m| m.configuration == c.name)
            .map(|m| m.budget)
            .fold(None, |acc: Option<BudgetPoint>, b| match (acc, b) {
                (Some(BudgetPoint::Spp(_)), BudgetPoint::TimeMs(_)) => acc,
                _ => Some(b),
            });
        let Some(last) = last else { continue };
        let ms: Vec<_> = results
            .measurements
            .iter()
            .filter(|m| m.configuration == c.name && m.budget == last)
            .collect();
        let mut parts: Vec<(String, f64)> = Vec::new();
        for m in &ms {
            for (stage, t) in &m.stages {
                let per = t / m.spp.max(1.0) / ms.len() as f64;
                match parts.iter_mut().find(|p| &p.0 == stage) {
                    Some(p) => p.1 += per,
                    None => parts.push((stage.clone(), per)),
                }
            }
        }
        // Bottom to top in the order a frame runs its passes.
        let order = |name: &str| {
            pathlight_render::frame::passes()
                .iter()
                .position(|p| *p == name)
                .unwrap_or(usize::MAX)
        };
        parts.sort_by_key(|p| order(&p.0));
        stacks.push(Stack {
            label: c.name.clone(),
            parts,
        });
    }
    let y = Axis {
        label: "ms per sample per pixel of the image".into(),
        log: false,
    };
    let png = plot::stacked_bar_chart("Time per stage", &y, &stacks, CHART.0, CHART.1)?;
    write(out, "plots/stages.png", &png)?;
    s.figures.push(figure(
        "plots/stages.png",
        "Milliseconds per sample per pixel, by stage",
    ));
    Ok(s)
}

/// Full images, error maps and crops next to the reference: one row with the reference and
/// each configuration's image, one with the error maps, then a row per crop.
fn images(
    results: &Results,
    snaps: &crate::experiment::Snapshots,
    out: &Path,
) -> Result<Section, EvalError> {
    let primary = results.spec.metrics[0];
    let reference = &snaps.reference;
    let (w, h) = (reference.width, reference.height);
    let side = ((w.min(h) as f32 * CROP_FRACTION) as u32).max(4);
    let rects = plot::pick_crops(reference, CROPS, side);
    // Full images at least IMAGE_DISPLAY pixels wide (integer upscaling).
    let shown = w * (IMAGE_DISPLAY / w.max(1)).max(1);
    let mut s = section(
        "Images",
        &format!(
            "View {} of the camera path. Each configuration at its last budget point (first repetition), its per-pixel {} error map (one colour scale for all maps: 0 to the 99th percentile over all of them), and {} crops (outlined on the reference in the colour of their number: 1 blue, 2 orange, 3 green) next to the reference's.",
            snaps.view,
            primary,
            rects.len()
        ),
    );
    write(
        out,
        "images/reference.png",
        &plot::image_with_rects_png(reference, &rects, 1.0),
    )?;
    let mut full = vec![picture(
        "images/reference.png",
        "Reference, with the crops outlined",
        shown,
    )];
    let maps: Vec<Vec<f32>> = snaps
        .images
        .iter()
        .map(|(_, _, image)| metrics::error_map(primary, image, reference))
        .collect::<Result<_, _>>()?;
    let max = percentile(maps.iter().flatten().copied(), 0.99);
    let mut errors = Vec::new();
    for (k, ((name, label, image), map)) in snaps.images.iter().zip(&maps).enumerate() {
        let slug = slug(k, name);
        let file = format!("images/{slug}.png");
        write(
            out,
            &file,
            &encode_png(w, h, &image.pixels, &Default::default()),
        )?;
        full.push(picture(&file, &format!("{name}: {label}"), shown));
        let file = format!("images/{slug}-error.png");
        let png = plot::error_map_png(map, w, h, Some(max), &error_label(primary))?;
        write(out, &file, &png)?;
        errors.push(figure(&file, &format!("{name}: {primary} error map")));
    }
    s.rows.push(full);
    s.rows.push(errors);
    if !snaps.displays.is_empty() {
        let mut row = Vec::new();
        for (name, mode, rgba) in &snaps.displays {
            let k = snaps.images.iter().position(|i| i.0 == *name).unwrap_or(0);
            let file = format!("images/{}-{}.png", slug(k, name), mode.name());
            write(out, &file, &encode_rgba8_png(w, h, rgba))?;
            row.push(picture(
                &file,
                &format!("{name}: display mode {}", mode.name()),
                shown,
            ));
        }
        s.rows.push(row);
    }
    for (i, &rect) in rects.iter().enumerate() {
        let scale = (CROP_DISPLAY / rect.width.max(1)).max(1);
        let mut row = Vec::new();
        let file = format!("images/crop{i}-reference.png");
        write(out, &file, &plot::crop_png(reference, rect, scale, 1.0))?;
        row.push(figure(&file, &format!("Crop {}: reference", i + 1)));
        for (k, ((name, _, image), map)) in snaps.images.iter().zip(&maps).enumerate() {
            let slug = slug(k, name);
            let file = format!("images/crop{i}-{slug}.png");
            write(out, &file, &plot::crop_png(image, rect, scale, 1.0))?;
            row.push(figure(&file, &format!("Crop {}: {name}", i + 1)));
            let values = plot::crop_values(map, w, rect);
            let file = format!("images/crop{i}-{slug}-error.png");
            let png = plot::error_map_png(
                &values,
                rect.width,
                rect.height,
                Some(max),
                &error_label(primary),
            )?;
            write(out, &file, &png)?;
            row.push(figure(
                &file,
                &format!("Crop {}: {name}, {primary} error", i + 1),
            ));
        }
        s.rows.push(row);
    }
    Ok(s)
}

fn error_label(metric: Metric) -> String {
    format!("per-pixel {metric}")
}

/// The `q` quantile of the finite values (0 when there are none; at least a tiny positive
/// number so that a perfect image still has a colour scale).
fn percentile(values: impl Iterator<Item = f32>, q: f64) -> f32 {
    let mut v: Vec<f32> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 1e-12;
    }
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    let (_, x, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    x.max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentile_and_slug() {
        assert_eq!(percentile((0..101).map(|i| i as f32), 0.99), 99.0);
        assert_eq!(percentile([f32::NAN].into_iter(), 0.5), 1e-12);
        assert_eq!(slug(2, "Sobol / 4 spp"), "2-sobol---4-spp");
        assert_eq!(slug(0, "../x"), "0-x");
    }
}
