//! Reference images: rendered by the reference path tracer at high spp, cached on disk under a
//! hash of the scene, the camera, the settings and the renderer's version, and reused across
//! runs. Long references are checkpointed, so a stopped run continues where it stopped.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use pathlight_render::checkpoint::{self, Header};
use pathlight_render::output::{read_exr_layer, write_atomic, write_film};
use pathlight_render::renderer::{pass_targets, render_pass};
use pathlight_render::{Config, Film, World};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::image::Image;
use crate::spec::Layer;
use crate::EvalError;

/// Changes whenever the reference path tracer's output changes (bump it with the renderer),
/// so that cached references of an older renderer are not reused.
pub const RENDERER_VERSION: &str = concat!("pathlight-render ", env!("CARGO_PKG_VERSION"), " r1");

/// Most samples per pixel in one pass of a reference render (checkpoint granularity).
const MAX_PASS: u32 = 16;
/// Seconds between checkpoints of a reference render.
const CHECKPOINT_EVERY: Duration = Duration::from_secs(30);

/// What identifies the scene in a cache key: the scene's file (and environment map) contents
/// and the loader's options. Files a scene refers to (buffers, textures, material libraries)
/// are covered by the scene's counts only, so edit the main file (or clear the cache) after
/// changing them.
pub struct SceneIdentity {
    pub description: String,
    digest: [u8; 32],
}

impl SceneIdentity {
    /// Hashes the scene file (none: the built-in Cornell box), the environment file, the
    /// loader options and the loaded scene's counts.
    pub fn new(
        scene: Option<&Path>,
        environment: Option<&Path>,
        options: &str,
        counts: &str,
    ) -> Result<Self, EvalError> {
        let mut h = Sha256::new();
        let mut description = String::new();
        for (label, path) in [("scene", scene), ("environment", environment)] {
            match path {
                Some(p) => {
                    let bytes = std::fs::read(p).map_err(|e| EvalError::io(p.to_owned(), e))?;
                    h.update(label.as_bytes());
                    h.update((bytes.len() as u64).to_le_bytes());
                    h.update(&bytes);
                    description += &format!("{label} {} ", p.display());
                }
                None if label == "scene" => {
                    h.update(b"built-in Cornell box");
                    description += "built-in Cornell box ";
                }
                None => {}
            }
        }
        h.update(options.as_bytes());
        h.update(counts.as_bytes());
        description += counts;
        Ok(Self {
            description,
            digest: h.finalize().into(),
        })
    }
}

/// Where references live: `<dir>/references/<key>.exr`, with `<key>.json` describing each.
pub struct ReferenceCache {
    pub dir: PathBuf,
}

/// A cached (or just rendered) reference.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReferenceInfo {
    pub key: String,
    pub path: PathBuf,
    pub scene: String,
    pub config: Config,
    pub renderer: String,
    /// Render time of the reference, in seconds (when it was made).
    pub render_seconds: f64,
    /// Mean over pixels and channels of the variance of the reference's mean (per-sample
    /// variance / spp): the MSE the reference itself contributes to any measured MSE.
    pub expected_mse: f64,
    /// True when this run found the reference in the cache.
    #[serde(default)]
    pub cached: bool,
}

impl ReferenceCache {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// The key of a reference of `scene` rendered with `config` (camera included). The
    /// real-time pipeline's settings (`config.frame`) do not count: the reference path tracer
    /// never reads them, and a new technique's switches must not invalidate every reference.
    /// The `frame` table is left out of the hash altogether, so that a technique's new
    /// settings (with their defaults) do not change the keys of existing references either.
    pub fn key(scene: &SceneIdentity, config: &Config) -> String {
        let mut traced = serde_json::to_value(config).expect("a Config serialises");
        if let Some(table) = traced.as_object_mut() {
            table.remove("frame");
        }
        let mut h = Sha256::new();
        h.update(RENDERER_VERSION.as_bytes());
        h.update(scene.digest);
        h.update(serde_json::to_vec(&traced).expect("a Config serialises"));
        h.finalize()[..16]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    fn paths(&self, key: &str) -> (PathBuf, PathBuf, PathBuf) {
        let d = self.dir.join("references");
        (
            d.join(format!("{key}.exr")),
            d.join(format!("{key}.json")),
            d.join(format!("{key}.checkpoint")),
        )
    }

    /// The cached reference for `key` (its `layer`), when there is a readable one of the right
    /// size (references cached before their layers were stored have no indirect layer).
    pub fn get(
        &self,
        key: &str,
        width: u32,
        height: u32,
        layer: Layer,
    ) -> Option<(Image, ReferenceInfo)> {
        let (exr, json, _) = self.paths(key);
        let info: ReferenceInfo = serde_json::from_slice(&std::fs::read(&json).ok()?).ok()?;
        let (w, h, pixels) = read_exr_layer(&exr, layer.exr_prefix()).ok()?;
        if (w, h) != (width, height) || pixels.iter().any(|p| !p.is_finite()) {
            log::warn!(
                "{}: unusable cached reference, rendering it again",
                exr.display()
            );
            return None;
        }
        Some((
            Image::new(w, h, pixels),
            ReferenceInfo {
                cached: true,
                ..info
            },
        ))
    }

    /// The reference for `config` of `world`: from the cache, or rendered (resuming from its
    /// checkpoint when one is there) and stored. Returns `Ok(None)` when cancelled (the
    /// checkpoint then holds what was done).
    pub fn get_or_render(
        &self,
        scene: &SceneIdentity,
        world: &World,
        config: &Config,
        layer: Layer,
        cancel: &AtomicBool,
        progress: &(dyn Fn(u64, u64) + Sync),
    ) -> Result<Option<(Image, ReferenceInfo)>, EvalError> {
        let key = Self::key(scene, config);
        if let Some(found) = self.get(&key, config.width, config.height, layer) {
            return Ok(Some(found));
        }
        let (exr, _, ckpt) = self.paths(&key);
        let dir = exr.parent().expect("a file in a folder");
        std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir.to_owned(), e))?;
        let header = Header {
            config: config.clone(),
            scene: scene.description.clone(),
            width: config.width,
            height: config.height,
            samples: None,
        };
        let mut film = match checkpoint::load(&ckpt) {
            Ok((h, film)) if h.compatible(&header) => {
                log::info!("{}: resuming the reference", ckpt.display());
                film
            }
            _ => Film::new(config.width, config.height),
        };
        let camera = config.render_camera(world);
        let total = config.width as u64 * config.height as u64 * config.spp as u64;
        let done = std::sync::atomic::AtomicU64::new(film.samples());
        progress(film.samples(), total);
        let start = Instant::now();
        let mut last_checkpoint = Instant::now();
        for target in pass_targets(film.min_samples(), config.spp, MAX_PASS) {
            let finished = render_pass(world, &camera, config, &mut film, target, cancel, &|n| {
                let d = done.fetch_add(n, std::sync::atomic::Ordering::Relaxed) + n;
                progress(d, total);
            });
            if !finished {
                checkpoint::save(&ckpt, &header, &film)?;
                return Ok(None);
            }
            if last_checkpoint.elapsed() >= CHECKPOINT_EVERY {
                checkpoint::save(&ckpt, &header, &film)?;
                last_checkpoint = Instant::now();
            }
        }
        let (image, info) = self.store(
            &key,
            scene,
            config,
            &film,
            start.elapsed().as_secs_f64(),
            layer,
        )?;
        let _ = std::fs::remove_file(&ckpt);
        Ok(Some((image, info)))
    }

    /// Stores `film`, the finished reference `key` of `scene` rendered with `config` in
    /// `render_seconds` (here, or on a cluster and merged), as the cache's image (with its
    /// layers: direct and indirect light, features) and description; returns its `layer`.
    pub fn store(
        &self,
        key: &str,
        scene: &SceneIdentity,
        config: &Config,
        film: &Film,
        render_seconds: f64,
        layer: Layer,
    ) -> Result<(Image, ReferenceInfo), EvalError> {
        let (exr, json, _) = self.paths(key);
        let dir = exr.parent().expect("a file in a folder");
        std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir.to_owned(), e))?;
        write_film(&exr, film, true, &Default::default())?;
        let info = ReferenceInfo {
            key: key.to_owned(),
            path: exr.clone(),
            scene: scene.description.clone(),
            config: config.clone(),
            renderer: RENDERER_VERSION.to_owned(),
            render_seconds,
            expected_mse: expected_mse(film),
            cached: false,
        };
        let text = serde_json::to_vec_pretty(&info).expect("serialisable");
        write_atomic(&json, &text)?;
        Ok((film_image(film, layer), info))
    }
}

/// The film's mean radiance (or its `layer`) as an image.
pub fn film_image(film: &Film, layer: Layer) -> Image {
    Image::new(
        film.width,
        film.height,
        match layer {
            Layer::Final => film.layer(|p| p.mean),
            Layer::Indirect => film.layer(|p| p.indirect),
        },
    )
}

/// Mean over pixels and channels of each pixel's variance of the mean.
pub fn expected_mse(film: &Film) -> f64 {
    let sum: f64 = film
        .pixels
        .iter()
        .map(|p| {
            let v = p.variance() / p.n.max(1) as f32;
            (v.x + v.y + v.z) as f64
        })
        .sum();
    sum / (3.0 * film.pixels.len().max(1) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_ignore_the_frame_pipeline_but_not_what_is_traced() {
        let scene = SceneIdentity::new(None, None, "", "counts").unwrap();
        let base = Config::default();
        let mut frame = base.clone();
        frame.frame.reprojection.enabled = true;
        frame.frame.adaptive.max_spp = 7;
        frame.frame.accumulate = false;
        frame.frame.filter.data_driven.kernel = 5;
        assert_eq!(
            ReferenceCache::key(&scene, &base),
            ReferenceCache::key(&scene, &frame)
        );
        let bounces = Config {
            max_bounces: Some(3),
            ..base.clone()
        };
        assert_ne!(
            ReferenceCache::key(&scene, &base),
            ReferenceCache::key(&scene, &bounces)
        );
    }
}
