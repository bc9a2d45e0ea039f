//! The real-time presets (whole configurations, `experiments/realtime*.toml`) and the rule
//! that chooses one from the scene's lights when the user gives no configuration (`view`,
//! `play` and `bench frame` without `--config` or `--plain`).
//!
//! The rule, set from the presets measured along camera moves (320x180, two bounces, relMSE
//! against converged references at each preset's median frame time):
//! - **no light** (nothing emits and no environment): the plain pipeline, since every
//!   technique would be spent on a black image;
//! - **many sources and no environment** (at least [`MANY_SOURCES`] emissive materials and
//!   punctual lights): the SVGF preset (`realtime.toml`): on the interior lit by 500 point
//!   lights (issue 60's table) 0.246 at 74 ms, where the cache's preset gave 0.956 at 68 ms
//!   (its cells' next event estimation over hundreds of lights is noise the cache then keeps)
//!   and ReSTIR's 0.211 at 106 ms; along `experiments/060-defaults.toml`'s pan 0.967 at 65 ms
//!   against the cache's 33.9 and ReSTIR's 2.41 at 119;
//! - **a few point lights and nothing else** (no environment, no emissive surface): the
//!   many-lights preset (`realtime-many-lights.toml`, SVGF with ReSTIR DI): along the pan the
//!   city diorama (lit by the 16 point lights the loader adds to an unlit scene) gave 0.128 at
//!   30 ms against SVGF's 0.157 at 28 and the cache's 1.1 at 36 (point lights close to the
//!   surfaces light a cell's corners unevenly, and the filter spreads it), the hotel room
//!   (the same 16 lights) 0.0078 at 22 against the cache's 0.0075 at 17;
//! - **otherwise** (a sky, a sun, a studio environment, a few lamps that are surfaces): the
//!   texture cache's preset (`realtime-sun.toml`): the best on the Cornell box (issue 60's
//!   table: 0.122 at 33 ms against SVGF's 0.165 at 33), the garden under its sky (0.138 at 40
//!   against 0.363 at 31) and the helmet in its studio (0.192 at 48 against 14.6 at 37, where
//!   SVGF smeared the visor's highlight), and along the pan on those three and the interior
//!   under its sky.
//!
//! The pan set the point-lights case; `experiments/060-defaults-orbit.toml` reports the rule
//! on another move (BENCHMARKS.md, "Real time by default (issue 60)"). Facts not used yet (the
//! issue's other candidates): how much of the view is glossy, metallic or textured. The
//! threshold between "a few" and "many" sources is not measured between 16 and 500; 64 is a
//! choice.

use crate::config::Config;
use crate::light::Lights;

/// The `preset` value (a configuration file's, an eval configuration's) that lets the rule
/// choose.
pub const AUTO: &str = "auto";

/// Every name `preset` takes: the presets' and [`AUTO`].
pub fn names() -> String {
    let mut names: Vec<_> = Preset::ALL.iter().map(|p| p.name()).collect();
    names.push(AUTO);
    names.join(", ")
}

/// Light sources (besides an environment) from which a scene counts as lit by many.
pub const MANY_SOURCES: usize = 64;

/// A configuration the frame commands can start from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// The plain path tracer: every technique off (`Config::realtime()`).
    Plain,
    /// SVGF with accumulation and its still handover (`experiments/realtime.toml`).
    Realtime,
    /// The real-time preset with ReSTIR DI (`experiments/realtime-many-lights.toml`): scenes
    /// lit by a few point lights alone.
    ManyLights,
    /// The texture-space shading cache, its sun apart, under TAA
    /// (`experiments/realtime-sun.toml`).
    Sun,
}

impl Preset {
    /// Every preset, in the order the viewer offers them.
    pub const ALL: [Preset; 4] = [Self::Plain, Self::Realtime, Self::ManyLights, Self::Sun];

    /// Its name (the viewer's button; `info`'s and `play`'s reports).
    pub fn name(self) -> &'static str {
        match self {
            Self::Plain => "plain",
            Self::Realtime => "realtime",
            Self::ManyLights => "realtime-many-lights",
            Self::Sun => "realtime-sun",
        }
    }

    /// Its file, from the repository's root (`None`: the plain pipeline has none).
    pub fn file(self) -> Option<&'static str> {
        match self {
            Self::Plain => None,
            Self::Realtime => Some("experiments/realtime.toml"),
            Self::ManyLights => Some("experiments/realtime-many-lights.toml"),
            Self::Sun => Some("experiments/realtime-sun.toml"),
        }
    }

    /// What it is for.
    pub fn about(self) -> &'static str {
        match self {
            Self::Plain => "the plain path tracer: one noisy sample a frame, no technique",
            Self::Realtime => "SVGF for a moving camera at 30 fps (scenes lit by many lamps)",
            Self::ManyLights => "SVGF with ReSTIR DI (scenes lit by a few point lights alone)",
            Self::Sun => "the texture-space cache (skies, suns, studios and a few lamps)",
        }
    }

    /// Its text (TOML), compiled in.
    pub fn text(self) -> &'static str {
        match self {
            Self::Plain => "max_bounces = 2\n",
            Self::Realtime => include_str!("../../../experiments/realtime.toml"),
            Self::ManyLights => include_str!("../../../experiments/realtime-many-lights.toml"),
            Self::Sun => include_str!("../../../experiments/realtime-sun.toml"),
        }
    }

    /// The preset as a whole configuration over `view`'s view of the scene
    /// ([`Config::with_preset`]).
    pub fn config(self, view: &Config) -> Config {
        view.with_preset(self.text())
            .expect("the presets compiled in parse (tests/preset.rs)")
    }

    /// The preset named `name` (one of [`name`](Self::name)'s).
    pub fn named(name: &str) -> Option<Preset> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
}

/// The preset the rule chose, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Choice {
    pub preset: Preset,
    pub reason: String,
}

/// `n` light sources, in words.
fn sources_text(n: usize) -> String {
    format!("{n} light source{}", if n == 1 { "" } else { "s" })
}

/// The rule (module docs): the preset for a scene lit by `lights`.
pub fn choose(lights: &Lights) -> Choice {
    let (sources, environment) = (lights.sources(), lights.has_environment());
    let only_points = !environment && lights.punctual_lights() == sources;
    let (preset, reason) = if sources == 0 && !environment {
        (
            Preset::Plain,
            "nothing emits light and there is no environment".to_string(),
        )
    } else if sources >= MANY_SOURCES && !environment {
        (
            Preset::Realtime,
            format!(
                "{} and no environment (many: at least {MANY_SOURCES})",
                sources_text(sources)
            ),
        )
    } else if only_points {
        (
            Preset::ManyLights,
            format!(
                "{} and nothing else: point lights alone (few: under {MANY_SOURCES})",
                sources_text(sources)
            ),
        )
    } else {
        let what = match (environment, sources) {
            (true, 0) => "an environment".to_string(),
            (true, n) => format!("an environment and {}", sources_text(n)),
            (false, n) => format!("{} (few: under {MANY_SOURCES})", sources_text(n)),
        };
        (Preset::Sun, what)
    };
    Choice { preset, reason }
}

#[cfg(test)]
mod tests {
    use glam::{Mat4, Vec3};
    use pathlight_scene::{Environment, PunctualKind, PunctualLight, Scene};

    use super::*;
    use crate::light::tests::{emissive_material, instance, mesh, sunny};

    /// A scene lit by `points` point lights, `lamps` emissive quads (each its own material)
    /// and `environment`.
    fn scene(points: usize, lamps: usize, environment: Option<Environment>) -> Scene {
        let mut s = Scene {
            environment,
            ..Scene::default()
        };
        for i in 0..lamps {
            s.materials
                .push(emissive_material(Vec3::splat(1.0 + i as f32), false));
            let quad = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z];
            s.meshes
                .push(mesh(quad, vec![[0, 2, 1], [0, 3, 2]], i as u32));
            let at = Mat4::from_translation(Vec3::new(2.0 * i as f32, 3.0, 0.0));
            s.instances.push(instance(i as u32, at));
        }
        s.lights = (0..points)
            .map(|i| PunctualLight {
                name: format!("p{i}"),
                kind: PunctualKind::Point,
                position: Vec3::new(i as f32, 2.0, 0.0),
                direction: Vec3::NEG_Y,
                intensity: Vec3::splat(1.0),
                range: None,
            })
            .collect();
        s.collect_emissive_triangles();
        s
    }

    fn chosen(s: &Scene) -> Preset {
        choose(&Lights::new(s, Default::default())).preset
    }

    /// The rule picks what the module docs say on a scene built for each case.
    #[test]
    fn the_rule_picks_what_its_documentation_says() {
        assert_eq!(chosen(&scene(0, 0, None)), Preset::Plain, "no light");
        assert_eq!(chosen(&scene(0, 1, None)), Preset::Sun, "a lamp");
        assert_eq!(chosen(&scene(2, 3, None)), Preset::Sun, "a few lamps");
        assert_eq!(
            chosen(&scene(16, 0, None)),
            Preset::ManyLights,
            "points alone"
        );
        assert_eq!(chosen(&scene(500, 0, None)), Preset::Realtime, "500 points");
        let sky = Some(sunny(32, 16));
        assert_eq!(
            chosen(&scene(0, 0, sky.clone())),
            Preset::Sun,
            "sun and sky"
        );
        assert_eq!(
            chosen(&scene(500, 0, sky)),
            Preset::Sun,
            "sky and 500 points"
        );
        let n = MANY_SOURCES;
        assert_eq!(
            chosen(&scene(n - 2, 1, None)),
            Preset::Sun,
            "under many, a lamp"
        );
        assert_eq!(
            chosen(&scene(n - 1, 1, None)),
            Preset::Realtime,
            "many, a lamp"
        );
        assert_eq!(
            chosen(&scene(n - 1, 0, None)),
            Preset::ManyLights,
            "under many"
        );
        assert_eq!(chosen(&scene(n, 0, None)), Preset::Realtime, "many points");
        let reason = choose(&Lights::new(&scene(500, 0, None), Default::default())).reason;
        assert!(reason.contains("500 light sources"), "{reason}");
    }

    /// Every preset compiled in parses, passes validation, names itself, and leaves the light
    /// selection alone (the frame commands load the world before the rule chooses).
    #[test]
    fn every_preset_parses_and_keeps_the_light_selection() {
        let base = Config::realtime();
        for p in Preset::ALL {
            let c = p.config(&base);
            c.validate().unwrap();
            assert_eq!(c.light_selection, base.light_selection, "{}", p.name());
            assert_eq!(Preset::named(p.name()), Some(p));
        }
        assert_eq!(Preset::Plain.config(&base), base);
        assert!(Preset::Sun.config(&base).frame.texture_cache.enabled);
    }
}
