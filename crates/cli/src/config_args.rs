//! Command-line options that set pathlight's one configuration type ([`Config`]), shared by
//! `render`, `view`, `play` and `bench frame`: a TOML file (`--config`) and flags that
//! override it.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use pathlight_render::bsdf::Microfacet;
use pathlight_render::config::Tonemap;
use pathlight_render::denoise::Method;
use pathlight_render::frame::adaptive::Measure;
use pathlight_render::frame::display::DisplayMode;
use pathlight_render::frame::views;
use pathlight_render::light::Lights;
use pathlight_render::preset::{self, Choice, Preset};
use pathlight_render::sampler::SamplerKind;
use pathlight_render::Config;

/// Largest configuration file read.
const MAX_CONFIG_BYTES: u64 = 1 << 20;

#[derive(Debug, Clone, Args)]
#[command(next_help_heading = "Configuration")]
pub struct ConfigArgs {
    /// Settings from a TOML file (any field of pathlight's configuration; see the README); the
    /// options below override it.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// The plain path tracer, every technique off, instead of the preset the scene's lights
    /// call for (`view`, `play` and `bench frame` without --config or a technique's flag
    /// choose one: `info` says which and why); for references, experiments and frame hashes.
    /// A --config file starts from the plain pipeline unless its `preset` key names another
    /// (`"auto"`: the rule's). `render` is always the plain path tracer.
    #[arg(long)]
    pub plain: bool,

    /// Image width in pixels.
    #[arg(long, value_name = "W")]
    pub width: Option<u32>,

    /// Image height in pixels.
    #[arg(long, value_name = "H")]
    pub height: Option<u32>,

    /// Samples per pixel (of the image for `render`, of each frame otherwise).
    #[arg(long, value_name = "N")]
    pub spp: Option<u32>,

    /// Seed of every random decision.
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,

    /// Maximum scattering events per path, or `unlimited` (Russian roulette ends paths).
    #[arg(long, value_name = "B|unlimited", value_parser = parse_bounces)]
    pub max_bounces: Option<Bounces>,

    /// Camera position (overrides the scene's camera).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_from: Option<[f32; 3]>,

    /// Point the camera looks at.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<[f32; 3]>,

    /// Camera up direction.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<[f32; 3]>,

    /// Vertical field of view.
    #[arg(long, value_name = "DEGREES")]
    pub fov_y: Option<f32>,

    /// Thin-lens radius in scene units (depth of field); 0 is a pinhole.
    #[arg(long, value_name = "R")]
    pub lens_radius: Option<f32>,

    /// Distance in focus [default: what the image centre sees].
    #[arg(long, value_name = "D")]
    pub focus_distance: Option<f32>,

    /// Microfacet distribution of glossy lobes: ggx or beckmann.
    #[arg(long, value_name = "NAME", value_parser = parse_microfacet)]
    pub microfacet: Option<Microfacet>,

    /// Sample values: sobol (Owen-scrambled Sobol points) or independent (plain Monte Carlo).
    #[arg(long, value_name = "NAME", value_parser = parse_sampler)]
    pub sampler: Option<SamplerKind>,

    /// Exposure multiplier before tone mapping.
    #[arg(long, value_name = "X")]
    pub exposure: Option<f32>,

    /// Tone mapping of 8-bit output: clamp or aces.
    #[arg(long, value_name = "NAME", value_parser = parse_tonemap)]
    pub tonemap: Option<Tonemap>,

    /// What frames show (view, play): one of the stages' views, by name.
    #[arg(long, value_name = "MODE", value_parser = parse_display())]
    pub display: Option<DisplayMode>,

    /// Frame pipeline: do not accumulate frames while the camera is still.
    #[arg(long)]
    pub no_accumulate: bool,

    /// Frame pipeline: stop accumulating after this many frames (0: never).
    #[arg(long, value_name = "N")]
    pub max_frames: Option<u32>,

    /// Frame pipeline: the frame time to hold, in ms, by lowering the render scale (temporal
    /// upsampling; 0: none). `[frame] target_ms` in a --config file.
    #[arg(long, value_name = "MS")]
    pub target_ms: Option<f32>,

    /// Frame pipeline: trace this fraction of the output's size per axis and reconstruct the
    /// output by temporal upsampling (1: the output's size; with --target-ms, the largest
    /// scale it may use). `[frame.upsample] scale` in a --config file.
    #[arg(long, value_name = "S")]
    pub render_scale: Option<f32>,

    /// Seed 000's adaptive sampling: samples where the pixels' variance is (with
    /// --reprojection: the combination; `=false` turns off a configuration's).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub adaptive: Option<bool>,

    /// Adaptive sampling: samples every pixel gets before the threshold applies [default: 4].
    #[arg(long, value_name = "N")]
    pub min_spp: Option<u32>,

    /// Adaptive sampling: the iteration at which each pixel's probability is fixed
    /// [default: 32].
    #[arg(long, value_name = "N")]
    pub max_spp: Option<u32>,

    /// Adaptive sampling: the measure V of a pixel's noise, luminance (the thesis's Eq. 12:
    /// relative), tonemapped (as displayed), absolute (in radiance, relative to the image's
    /// mean: samples in proportion to the noise) or error (absolute over the pixel's samples:
    /// the combination's best; the default).
    #[arg(long, value_name = "MEASURE", value_parser = parse_measure)]
    pub adaptive_measure: Option<Measure>,

    /// Adaptive sampling: the combination's fix, no pixel past max spp (on by default;
    /// `--adaptive-cap=false`: the thesis's).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub adaptive_cap: Option<bool>,

    /// Adaptive sampling: every frame traces a uniform frame's number of samples,
    /// distributed by the pixels' probabilities (not in the thesis; on by default,
    /// `--adaptive-budget=false`: the thesis's frames of one iteration).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub adaptive_budget: Option<bool>,

    /// Seed 000's forward reprojection: keep the samples that stay valid when the camera
    /// moves (`=false` turns off a configuration's).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub reprojection: Option<bool>,

    /// Reprojection: states per pixel, 1 or 4 [default: 1].
    #[arg(long, value_name = "N")]
    pub reprojection_samples: Option<u32>,

    /// Reprojection: largest view-dependency error (Eq. 15) kept [default: 1/256].
    #[arg(long, value_name = "X")]
    pub max_error: Option<f32>,

    /// Reprojection: after a move, a pixel holding fewer samples (a hole) takes the missing
    /// ones at once [default: 0, off: one per frame as the thesis]. (The texture cache's
    /// young cells have their own: `[frame.texture_cache] fresh_spp` in a --config file.)
    #[arg(long, value_name = "N")]
    pub fresh_spp: Option<u32>,

    /// Seed 004's ReSTIR direct illumination at the first hit (`[frame.restir] enabled`;
    /// `=false` turns off a configuration's).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub restir: Option<bool>,

    /// ReSTIR: light candidates per pixel, 1..1024 [default: 32].
    #[arg(long, value_name = "N")]
    pub candidates: Option<u32>,

    /// ReSTIR: the unbiased combination (1/Z with visibility) instead of the plain one.
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub restir_unbiased: Option<bool>,

    /// ReSTIR: combine with the paper's MIS weights (generalised balance heuristic).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub restir_mis: Option<bool>,

    /// Seed 002's texture-space shading cache (`[frame.texture_cache] enabled`; `=false`
    /// turns off a configuration's).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub texture_cache: Option<bool>,

    /// Texture cache: both caches' memory in MB [default: 64].
    #[arg(long, value_name = "MB")]
    pub texture_cache_budget: Option<f32>,

    /// Texture cache: levels added to the footprint's (coarser texels) [default: 1].
    #[arg(long, value_name = "LEVELS")]
    pub lod_bias: Option<f32>,

    /// Seed 001's reconstruction filter (`[frame.filter] method`): none, data-driven (of the
    /// accumulated image), svgf (spatio-temporal, of each frame's samples), taa (SVGF's
    /// temporal antialiasing alone) or rpf (Random Parameter Filtering, offline: `render`
    /// only).
    #[arg(long, value_name = "METHOD", value_parser = parse_filter)]
    pub filter: Option<Method>,

    /// Data-driven filter: the window's width in pixels, odd [default: 21].
    #[arg(long, value_name = "N")]
    pub kernel: Option<u32>,

    /// Data-driven filter: every other pixel of the window ("with holes", about 3x faster).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub holes: Option<bool>,
}

fn parse_filter(s: &str) -> Result<Method, String> {
    match s {
        "none" => Ok(Method::None),
        "data-driven" => Ok(Method::DataDriven),
        "svgf" => Ok(Method::Svgf),
        "rpf" => Ok(Method::Rpf),
        "taa" => Ok(Method::Taa),
        _ => Err(format!(
            "unknown filter {s:?}; one of none, data-driven, svgf, taa, rpf (rpf: `render` only)"
        )),
    }
}

fn parse_measure(s: &str) -> Result<Measure, String> {
    Measure::ALL
        .into_iter()
        .find(|m| m.name() == s)
        .ok_or_else(|| {
            let names: Vec<&str> = Measure::ALL.iter().map(|m| m.name()).collect();
            format!("unknown measure {s:?}; one of {}", names.join(", "))
        })
}

/// A bounce limit: a number, or none.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bounces(pub Option<u32>);

fn parse_bounces(s: &str) -> Result<Bounces, String> {
    if s == "unlimited" {
        return Ok(Bounces(None));
    }
    s.parse::<u32>()
        .map(|n| Bounces(Some(n)))
        .map_err(|_| format!("{s:?}: a number of bounces or `unlimited`"))
}

pub fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got {s:?}"));
    }
    let mut out = [0.0; 3];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{p:?} is not a finite number"))?;
    }
    Ok(out)
}

/// Parses `WxH` (e.g. `1280x720`), each between 1 and 16384.
pub fn parse_size(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, got {s:?}"))?;
    let side = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| format!("{v:?}: a size between 1 and 16384"))
    };
    Ok([side(w)?, side(h)?])
}

/// Parses a configuration enum by its serde name (the same names as in TOML files).
fn parse_named<T: serde::de::DeserializeOwned>(s: &str, names: &str) -> Result<T, String> {
    serde_json::from_value(serde_json::Value::String(s.to_owned()))
        .map_err(|_| format!("{s:?}: one of {names}"))
}

fn parse_microfacet(s: &str) -> Result<Microfacet, String> {
    parse_named(s, "ggx, beckmann")
}

fn parse_sampler(s: &str) -> Result<SamplerKind, String> {
    parse_named(s, "sobol, independent")
}

fn parse_tonemap(s: &str) -> Result<Tonemap, String> {
    parse_named(s, "clamp, aces")
}

/// The stages' views, by name (`--help` lists them).
fn parse_display() -> impl clap::builder::TypedValueParser<Value = DisplayMode> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(views::names())
        .map(|name| name.parse::<DisplayMode>().expect("one of the views"))
}

/// A configuration file's `preset` key (what its settings apply over: a preset's name,
/// `"auto"` or `"plain"`) and the rest of its text.
fn read_config(path: &std::path::Path) -> Result<(Option<String>, String)> {
    let meta = std::fs::metadata(path).with_context(|| format!("{}", path.display()))?;
    if meta.len() > MAX_CONFIG_BYTES {
        bail!(
            "{}: {} bytes; a configuration is at most {MAX_CONFIG_BYTES} bytes",
            path.display(),
            meta.len()
        );
    }
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let mut table: toml::Table = text
        .parse()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    match table.remove("preset") {
        None => Ok((None, text)),
        Some(toml::Value::String(name)) => Ok((Some(name), table.to_string())),
        Some(v) => bail!(
            "{}: preset = {v}: must be a string, one of {}",
            path.display(),
            preset::names()
        ),
    }
}

/// The rule's choice for the commands' JSON reports: `{"name", "reason"}`, or null when the
/// command line gave the configuration (--config or --plain).
pub fn choice_json(choice: &Option<Choice>) -> serde_json::Value {
    choice.as_ref().map_or(
        serde_json::Value::Null,
        |c| serde_json::json!({"name": c.preset.name(), "reason": c.reason}),
    )
}

impl ConfigArgs {
    /// The frame commands' configuration for a scene lit by `lights`: with neither --config,
    /// --plain nor a technique's flag ([`technique_flags`](Self::technique_flags)), or with a
    /// --config file whose `preset` is `"auto"`, the preset the rule chooses
    /// ([`preset::choose`], returned with its reason) holding the default frame-time target
    /// ([`DEFAULT_MS`](pathlight_render::frame::target::DEFAULT_MS)); else the plain pipeline
    /// or the file's `preset`, without a target; then the file's settings and the flags
    /// ([`apply`](Self::apply)). The presets leave the light selection as it is, so `lights`
    /// stay those of the configuration.
    /// Checked ([`check_realtime`]); the choice is printed with its reason.
    pub fn for_scene(&self, lights: &Lights) -> Result<(Config, Option<Choice>)> {
        let file = match &self.config {
            Some(path) => Some(read_config(path)?),
            None => None,
        };
        let named = file.as_ref().and_then(|(name, _)| name.as_deref());
        let auto = !self.plain
            && match named {
                None => self.config.is_none() && self.technique_flags().is_empty(),
                Some(name) => name == preset::AUTO,
            };
        let (base, choice) = if auto {
            // The defaults hold a frame rate: the chosen preset at the default target.
            let choice = preset::choose(lights);
            let mut view = Config::realtime();
            view.frame.target_ms = pathlight_render::frame::target::DEFAULT_MS;
            (choice.preset.config(&view), Some(choice))
        } else {
            let preset = match named {
                None => Preset::Plain,
                Some(name) => Preset::named(name).with_context(|| {
                    format!(
                        "{}: preset = \"{name}\": must be one of {}",
                        self.config
                            .as_ref()
                            .map_or("".into(), |p| p.display().to_string()),
                        preset::names()
                    )
                })?,
            };
            (preset.config(&Config::realtime()), None)
        };
        let text = file.as_ref().map(|(_, text)| text.as_str());
        let config = self.apply_text(base, text)?;
        check_realtime(&config)?;
        if let Some(c) = &choice {
            eprintln!(
                "preset: {} ({}; --plain for none)",
                c.preset.name(),
                c.reason
            );
        }
        if config.frame.target_ms > 0.0 {
            eprintln!(
                "frame-time target: {} ms (the render scale adapts; --target-ms 0 for none)",
                config.frame.target_ms
            );
        }
        Ok((config, choice))
    }

    /// The configuration: `base`, then the `--config` file, then the flags. Not checked yet:
    /// the caller may still fill in values (e.g. the height from the camera's aspect ratio)
    /// before [`check`].
    pub fn apply(&self, base: Config) -> Result<Config> {
        let file = match &self.config {
            Some(path) => Some(read_config(path)?.1),
            None => None,
        };
        self.apply_text(base, file.as_deref())
    }

    /// [`apply`](Self::apply) with the `--config` file's text (its `preset` key taken out)
    /// already read.
    fn apply_text(&self, base: Config, file: Option<&str>) -> Result<Config> {
        let mut c = match (file, &self.config) {
            (Some(text), Some(path)) => base
                .with_toml(text)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
            _ => base,
        };
        if let Some(v) = self.width {
            c.width = v;
        }
        if let Some(v) = self.height {
            c.height = v;
        }
        if let Some(v) = self.spp {
            c.spp = v;
        }
        if let Some(v) = self.seed {
            c.seed = v;
        }
        if let Some(Bounces(v)) = self.max_bounces {
            c.max_bounces = v;
        }
        let cam = &mut c.camera;
        cam.look_from = self.look_from.or(cam.look_from);
        cam.look_at = self.look_at.or(cam.look_at);
        cam.up = self.up.or(cam.up);
        cam.fov_y = self.fov_y.or(cam.fov_y);
        if let Some(v) = self.lens_radius {
            cam.lens_radius = v;
        }
        cam.focus_distance = self.focus_distance.or(cam.focus_distance);
        if let Some(v) = self.microfacet {
            c.microfacet = v;
        }
        if let Some(v) = self.sampler {
            c.sampler = v;
        }
        if let Some(v) = self.exposure {
            c.display.exposure = v;
        }
        if let Some(v) = self.tonemap {
            c.display.tonemap = v;
        }
        if let Some(v) = self.display.clone() {
            c.display.mode = v;
        }
        if self.no_accumulate {
            c.frame.accumulate = false;
        }
        if let Some(v) = self.max_frames {
            c.frame.max_frames = v;
        }
        if let Some(v) = self.target_ms {
            c.frame.target_ms = v;
        }
        if let Some(v) = self.render_scale {
            c.frame.upsample.scale = v;
        }
        let (adaptive, reprojection) = (&mut c.frame.adaptive, &mut c.frame.reprojection);
        adaptive.enabled = self.adaptive.unwrap_or(adaptive.enabled);
        adaptive.min_spp = self.min_spp.unwrap_or(adaptive.min_spp);
        adaptive.max_spp = self.max_spp.unwrap_or(adaptive.max_spp);
        adaptive.measure = self.adaptive_measure.unwrap_or(adaptive.measure);
        adaptive.cap = self.adaptive_cap.unwrap_or(adaptive.cap);
        adaptive.budget = self.adaptive_budget.unwrap_or(adaptive.budget);
        reprojection.enabled = self.reprojection.unwrap_or(reprojection.enabled);
        reprojection.samples = self.reprojection_samples.unwrap_or(reprojection.samples);
        reprojection.max_error = self.max_error.unwrap_or(reprojection.max_error);
        reprojection.fresh_spp = self.fresh_spp.unwrap_or(reprojection.fresh_spp);
        let restir = &mut c.frame.restir;
        restir.enabled = self.restir.unwrap_or(restir.enabled);
        restir.candidates = self.candidates.unwrap_or(restir.candidates);
        restir.unbiased = self.restir_unbiased.unwrap_or(restir.unbiased);
        restir.mis = self.restir_mis.unwrap_or(restir.mis);
        let cache = &mut c.frame.texture_cache;
        cache.enabled = self.texture_cache.unwrap_or(cache.enabled);
        cache.budget_mb = self.texture_cache_budget.unwrap_or(cache.budget_mb);
        cache.lod_bias = self.lod_bias.unwrap_or(cache.lod_bias);
        let filter = &mut c.frame.filter;
        filter.method = self.filter.unwrap_or(filter.method);
        filter.data_driven.kernel = self.kernel.unwrap_or(filter.data_driven.kernel);
        filter.data_driven.holes = self.holes.unwrap_or(filter.data_driven.holes);
        Ok(c)
    }
}

impl ConfigArgs {
    /// The flags given that choose or tune a technique (the frame-only flags but the display
    /// and accumulation, and the filter's): with one, the command line composes its own frame
    /// over the plain pipeline instead of the preset the rule would choose.
    pub fn technique_flags(&self) -> Vec<&'static str> {
        let mut flags: Vec<_> = self
            .frame_only_flags()
            .into_iter()
            .filter(|f| {
                !matches!(
                    *f,
                    "--display"
                        | "--no-accumulate"
                        | "--max-frames"
                        | "--target-ms"
                        | "--render-scale"
                )
            })
            .collect();
        let filter = [
            ("--filter", self.filter.is_some()),
            ("--kernel", self.kernel.is_some()),
            ("--holes", self.holes.is_some()),
        ];
        flags.extend(filter.into_iter().filter(|(_, on)| *on).map(|(f, _)| f));
        flags
    }

    /// The flags given that only the frame pipeline reads (its stages, their parameters and
    /// the display mode), by name: `render`, the reference path tracer, refuses them.
    pub fn frame_only_flags(&self) -> Vec<&'static str> {
        let given = [
            ("--display", self.display.is_some()),
            ("--no-accumulate", self.no_accumulate),
            ("--max-frames", self.max_frames.is_some()),
            ("--target-ms", self.target_ms.is_some()),
            ("--render-scale", self.render_scale.is_some()),
            ("--adaptive", self.adaptive.is_some()),
            ("--min-spp", self.min_spp.is_some()),
            ("--max-spp", self.max_spp.is_some()),
            ("--adaptive-measure", self.adaptive_measure.is_some()),
            ("--adaptive-cap", self.adaptive_cap.is_some()),
            ("--adaptive-budget", self.adaptive_budget.is_some()),
            ("--reprojection", self.reprojection.is_some()),
            (
                "--reprojection-samples",
                self.reprojection_samples.is_some(),
            ),
            ("--max-error", self.max_error.is_some()),
            ("--fresh-spp", self.fresh_spp.is_some()),
            ("--restir", self.restir.is_some()),
            ("--candidates", self.candidates.is_some()),
            ("--restir-unbiased", self.restir_unbiased.is_some()),
            ("--restir-mis", self.restir_mis.is_some()),
            ("--texture-cache", self.texture_cache.is_some()),
            (
                "--texture-cache-budget",
                self.texture_cache_budget.is_some(),
            ),
            ("--lod-bias", self.lod_bias.is_some()),
        ];
        (given.into_iter())
            .filter(|(_, on)| *on)
            .map(|(flag, _)| flag)
            .collect()
    }
}

/// [`Config::validate`] as a command-line error.
pub fn check(c: &Config) -> Result<()> {
    if let Err(e) = c.validate() {
        bail!("{} {}: must be {}", e.option(), e.value, e.requirement);
    }
    Ok(())
}

/// [`check`] for the real-time commands (view, play, bench frame), which cannot run the
/// offline filter.
pub fn check_realtime(c: &Config) -> Result<()> {
    check(c)?;
    if c.frame.filter.method == Method::Rpf {
        bail!(
            "--filter rpf: Random Parameter Filtering is offline (every sample filtered apart): run it with `pathlight render --filter rpf` or in an eval configuration"
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        settings: ConfigArgs,
    }

    fn apply(args: &[&str]) -> Config {
        let cli = Cli::try_parse_from(std::iter::once("pathlight").chain(args.iter().copied()))
            .expect("the arguments parse");
        cli.settings.apply(Config::default()).expect("they apply")
    }

    /// Every switch turns on what it names, and `=false` turns off what a configuration file
    /// turned on.
    #[test]
    fn a_switch_set_to_false_turns_off_a_configuration_files() {
        let dir = std::env::temp_dir().join(format!("pathlight-switches-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("on.toml");
        std::fs::write(
            &file,
            "[frame.adaptive]\nenabled = true\n[frame.reprojection]\nenabled = true\n\
             [frame.restir]\nenabled = true\nunbiased = true\nmis = true\n\
             [frame.texture_cache]\nenabled = true\n[frame.filter.data_driven]\nholes = true\n",
        )
        .unwrap();
        let f = file.to_str().unwrap();
        let switches = |c: &Config| {
            let fr = &c.frame;
            [
                fr.adaptive.enabled,
                fr.reprojection.enabled,
                fr.restir.enabled,
                fr.restir.unbiased,
                fr.restir.mis,
                fr.texture_cache.enabled,
                fr.filter.data_driven.holes,
            ]
        };
        let names = [
            "--adaptive",
            "--reprojection",
            "--restir",
            "--restir-unbiased",
            "--restir-mis",
            "--texture-cache",
            "--holes",
        ];
        assert_eq!(switches(&apply(&["--config", f])), [true; 7]);
        assert_eq!(switches(&apply(&[])), [false; 7]);
        let off: Vec<String> = names.iter().map(|n| format!("{n}=false")).collect();
        let mut args = vec!["--config", f];
        args.extend(off.iter().map(String::as_str));
        assert_eq!(switches(&apply(&args)), [false; 7]);
        assert_eq!(switches(&apply(&names)), [true; 7]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
