//! `pathlight info`: load a scene and print what is in it, how long loading took and how much
//! memory it needed.

use pathlight_render::preset::Choice;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use clap::Args;
use pathlight_core::glam::Vec3;
use pathlight_scene::{Scene, SceneStats};
use serde_json::{json, Value};

use crate::memory::peak_rss_bytes;
use crate::scene_args::SceneArgs;

#[derive(Debug, Clone, Args)]
pub struct InfoArgs {
    #[command(flatten)]
    pub scene: SceneArgs,

    /// Print one JSON object (as the last line of stdout) instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// What `info` reports: the scene's statistics plus the measurements of its load.
struct Report<'a> {
    scene: &'a Scene,
    stats: SceneStats,
    load_ms: f64,
    peak_rss_bytes: Option<u64>,
    /// The environment's sun, as the texture cache's `terms = "sky"` and the sun preset split
    /// it from the sky (`light::sun`): its texels and its share of the environment's power.
    sun: Option<(usize, f32)>,
    /// The preset `view`, `play` and `bench frame` choose for the scene without a
    /// configuration ([`pathlight_render::preset::choose`]).
    choice: Choice,
}

/// The environment's sun (`None`: no environment, or none of its texels is a sun) and the
/// preset the scene's lights call for.
fn lights(scene: &Scene) -> (Option<(usize, f32)>, Choice) {
    let lights = pathlight_render::light::Lights::new(scene, Default::default());
    let choice = pathlight_render::preset::choose(&lights);
    if scene.environment.is_none() {
        return (None, choice);
    }
    let split = pathlight_render::light::sun::SunAndSky::new(&lights);
    let sun = split
        .has_sun()
        .then_some((split.sun_texels, split.sun_share));
    (sun, choice)
}

pub fn run(args: &InfoArgs) -> Result<()> {
    let options = args.scene.load_options();
    let path = args.scene.scene.as_deref();
    log::info!(
        "loading {}",
        path.map_or("the built-in Cornell box".into(), |p| p
            .display()
            .to_string())
    );
    let start = Instant::now();
    let scene = pathlight_scene::load(path, &options)?;
    let load_ms = start.elapsed().as_secs_f64() * 1e3;
    let peak_rss_bytes = peak_rss_bytes();
    let (sun, choice) = lights(&scene);
    let report = Report {
        stats: scene.stats(),
        sun,
        choice,
        scene: &scene,
        load_ms,
        peak_rss_bytes,
    };
    if args.json {
        println!("{}", serde_json::to_string(&report.to_json())?);
    } else {
        print!("{}", report.to_table());
    }
    Ok(())
}

impl Report<'_> {
    /// The scene's emitted power, with the `-0.0` of an empty sum shown as `0`.
    fn emissive_power(&self) -> f32 {
        self.scene.emissive_power() + 0.0
    }

    fn to_json(&self) -> Value {
        let s = &self.stats;
        let bounds = if s.bounds.is_empty() {
            Value::Null
        } else {
            json!({
                "min": s.bounds.min.to_array(),
                "max": s.bounds.max.to_array(),
            })
        };
        let environment = self.scene.environment.as_ref();
        json!({
            "file": self.scene.path.as_deref().map(Path::display).map(|d| d.to_string()),
            "name": self.scene.name,
            "triangles": s.triangles,
            "unique_triangles": s.unique_triangles,
            "dropped_triangles": s.dropped_triangles,
            "vertices": s.vertices,
            "meshes": s.meshes,
            "instances": s.instances,
            "materials": s.materials,
            "textures": s.textures,
            "texture_pixels": s.texture_pixels,
            "emissive_triangles": s.emissive_triangles,
            "emissive_power": self.emissive_power(),
            "punctual_lights": s.punctual_lights,
            "cameras": s.cameras,
            "environment": s.environment,
            "environment_name": environment.map(|e| e.name.clone()),
            "environment_size": environment.map(|e| [e.width, e.height]),
            "sun": self.sun.map(|(texels, share)| json!({"texels": texels, "share": share})),
            "preset": json!({
                "name": self.choice.preset.name(),
                "reason": self.choice.reason,
                "target_ms": pathlight_render::frame::target::DEFAULT_MS,
            }),
            "bounds": bounds,
            "load_ms": self.load_ms,
            "peak_rss_bytes": self.peak_rss_bytes,
            "heap_bytes": s.heap_bytes,
            "warnings": self.scene.warnings,
        })
    }

    fn to_table(&self) -> String {
        let s = &self.stats;
        let scene = self.scene;
        let mut rows: Vec<(&str, String)> = Vec::new();
        let name = if scene.name.is_empty() {
            "(unnamed)".to_string()
        } else {
            scene.name.clone()
        };
        rows.push(("scene", name));
        rows.push((
            "file",
            scene
                .path
                .as_deref()
                .map_or("(built in)".into(), |p| p.display().to_string()),
        ));
        rows.push(("triangles", format!("{} (instanced)", group(s.triangles))));
        rows.push(("unique triangles", group(s.unique_triangles)));
        rows.push((
            "dropped triangles",
            format!("{} (degenerate or non-finite)", group(s.dropped_triangles)),
        ));
        rows.push(("vertices", group(s.vertices)));
        rows.push(("meshes", group(s.meshes as u64)));
        rows.push(("instances", group(s.instances as u64)));
        rows.push(("materials", group(s.materials as u64)));
        rows.push((
            "textures",
            format!(
                "{} ({} pixels)",
                group(s.textures as u64),
                group(s.texture_pixels)
            ),
        ));
        rows.push((
            "emissive triangles",
            format!(
                "{} (power {:.4} W)",
                group(s.emissive_triangles as u64),
                self.emissive_power()
            ),
        ));
        rows.push(("punctual lights", group(s.punctual_lights as u64)));
        rows.push(("cameras", group(s.cameras as u64)));
        rows.push((
            "environment",
            scene.environment.as_ref().map_or("none".into(), |e| {
                format!("{} ({}x{})", e.name, e.width, e.height)
            }),
        ));
        rows.push((
            "sun",
            self.sun.map_or("none".into(), |(texels, share)| {
                format!(
                    "{texels} texels of the environment, {:.1}% of its power",
                    100.0 * share
                )
            }),
        ));
        rows.push((
            "preset",
            format!(
                "{} ({}) holding {} ms a frame, what view, play and bench frame run without \
                 --config or --plain",
                self.choice.preset.name(),
                self.choice.reason,
                pathlight_render::frame::target::DEFAULT_MS
            ),
        ));
        if s.bounds.is_empty() {
            rows.push(("bounds", "empty".into()));
        } else {
            rows.push(("bounds min", vec3(s.bounds.min)));
            rows.push(("bounds max", vec3(s.bounds.max)));
            rows.push(("bounds size", vec3(s.bounds.diagonal())));
        }
        rows.push(("load time", format!("{:.1} ms", self.load_ms)));
        rows.push((
            "peak memory",
            self.peak_rss_bytes
                .map_or("unavailable".into(), |b| format!("{} (peak RSS)", mib(b))),
        ));
        rows.push((
            "scene heap",
            format!("{} ({} bytes)", mib(s.heap_bytes), group(s.heap_bytes)),
        ));
        rows.push(("warnings", group(s.warnings as u64)));

        let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
        let mut out = String::new();
        for (key, value) in rows {
            out.push_str(&format!("{key:<width$}  {value}\n"));
        }
        out
    }
}

/// `1234567` as `1,234,567`.
fn group(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    // A comma goes before every digit whose index has the remainder of the length mod 3.
    let phase = digits.len() % 3;
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && i % 3 == phase {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

fn vec3(v: Vec3) -> String {
    format!("({}, {}, {})", num(v.x), num(v.y), num(v.z))
}

/// A coordinate with 4 significant digits, without exponent for everyday magnitudes.
fn num(x: f32) -> String {
    let a = x.abs();
    if a != 0.0 && !(1e-3..1e7).contains(&a) {
        format!("{x:.3e}")
    } else {
        let decimals = if a >= 1000.0 {
            0
        } else if a >= 1.0 {
            3 - a.log10().floor() as usize
        } else {
            4
        };
        format!("{x:.decimals$}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_thousands() {
        assert_eq!(group(0), "0");
        assert_eq!(group(999), "999");
        assert_eq!(group(1000), "1,000");
        assert_eq!(group(177_934), "177,934");
        assert_eq!(group(100_000_000), "100,000,000");
    }

    #[test]
    fn formats_coordinates() {
        assert_eq!(num(0.0), "0.0000");
        assert_eq!(num(1.5), "1.500");
        assert_eq!(num(-12.25), "-12.25");
        assert_eq!(num(12_345.6), "12346");
        assert_eq!(num(0.25), "0.2500");
        assert_eq!(num(1e-5), "1.000e-5");
    }

    #[test]
    fn json_of_an_empty_scene_has_every_key() {
        let scene = Scene::default();
        let report = Report {
            stats: scene.stats(),
            scene: &scene,
            load_ms: 1.0,
            peak_rss_bytes: None,
            sun: lights(&scene).0,
            choice: lights(&scene).1,
        };
        let v = report.to_json();
        for key in [
            "file",
            "triangles",
            "unique_triangles",
            "dropped_triangles",
            "vertices",
            "meshes",
            "instances",
            "materials",
            "textures",
            "emissive_triangles",
            "punctual_lights",
            "cameras",
            "environment",
            "sun",
            "preset",
            "bounds",
            "load_ms",
            "peak_rss_bytes",
            "warnings",
        ] {
            assert!(v.get(key).is_some(), "missing key {key}");
        }
        assert_eq!(v["bounds"], Value::Null);
        assert_eq!(v["environment"], Value::Bool(false));
        assert!(report.to_table().contains("bounds  "));
    }
}
