//! [`EmbreeAccel`]: Intel Embree 3 behind the [`Accel`] interface, to measure the native BVH
//! against (feature `embree`; needs the Embree 3 library, Debian: `libembree-dev`).
//!
//! One triangle geometry holds the scene's world-space triangles, flattened over instances
//! exactly as the native backend gets them ([`SceneTriangles`]), so both trace the same
//! triangles. Embree's `primID` is the index into [`SceneTriangles`], mapped back to
//! (instance, triangle) through `SceneTriangles::ids`; Embree's `u, v` are the same
//! barycentrics as ours (the hit is (1 - u - v) p0 + u p1 + v p2).
//!
//! Differences from [`Accel`]'s contract: Embree accepts hits with `t_min < t <= t_max`
//! (strictly beyond `t_min`), where the trait says `t_min <= t`; no ray of the benchmarks or
//! tests lands exactly on `t_min`.
//!
//! The bindings (`embree3` 0.4) are safe wrappers around `rtcIntersect1`, `rtcOccluded1` and
//! `rtcIntersect1M`/`rtcOccluded1M`, so this module needs no `unsafe` of its own.

use std::sync::atomic::{AtomicIsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use embree3::{
    BufferUsage, BuildQuality, Config, Device, Format, GeometryKind, IntersectContext, RayHit,
    Scene, SceneFlags, INVALID_ID,
};

use crate::geometry::SceneTriangles;
use crate::ray::{Hit, Ray};
use crate::Accel;

/// How Embree builds its BVH.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EmbreeOptions {
    /// `RTC_BUILD_QUALITY_LOW`, `MEDIUM` (Embree's default) or `HIGH` (spatial splits; what
    /// renderers use for final frames of static scenes).
    pub quality: BuildQuality,
    /// `RTC_SCENE_FLAG_ROBUST`: watertight triangle tests and conservative box tests, like the
    /// native BVH (which never lets a ray slip between triangles sharing an edge).
    pub robust: bool,
    /// `RTC_SCENE_FLAG_COMPACT`: smaller, slower structure.
    pub compact: bool,
    /// Embree build threads; 0 means the current rayon pool's size (so a benchmark in a pool of
    /// T threads builds both backends with T threads).
    pub threads: usize,
}

impl Default for EmbreeOptions {
    /// The fair opponent for a static scene: high quality (spatial splits) and robust
    /// (watertight, as the native BVH is), not compact.
    fn default() -> Self {
        Self {
            quality: BuildQuality::HIGH,
            robust: true,
            compact: false,
            threads: 0,
        }
    }
}

impl EmbreeOptions {
    /// A short description, e.g. "high, robust".
    pub fn describe(&self) -> String {
        let quality = match self.quality {
            BuildQuality::LOW => "low",
            BuildQuality::MEDIUM => "medium",
            BuildQuality::HIGH => "high",
            BuildQuality::REFIT => "refit",
        };
        let mut s = format!("quality {quality}");
        if self.robust {
            s.push_str(", robust");
        }
        if self.compact {
            s.push_str(", compact");
        }
        s
    }
}

/// Why Embree could not build.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EmbreeError(pub String);

impl std::fmt::Display for EmbreeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "embree: {}", self.0)
    }
}

impl std::error::Error for EmbreeError {}

/// An Embree scene over a scene's world-space triangles.
pub struct EmbreeAccel {
    // Field order matters for drop order: the scene before its device.
    scene: Scene<'static>,
    _device: Device,
    ids: Vec<(u32, u32)>,
    /// Bytes Embree reports allocated on this accel's device (its memory monitor).
    allocated: Arc<AtomicIsize>,
    options: EmbreeOptions,
    build_seconds: f64,
}

impl EmbreeAccel {
    /// Builds with [`EmbreeOptions::default`].
    pub fn new(triangles: &SceneTriangles) -> Result<Self, EmbreeError> {
        Self::with_options(triangles, EmbreeOptions::default())
    }

    pub fn with_options(
        triangles: &SceneTriangles,
        options: EmbreeOptions,
    ) -> Result<Self, EmbreeError> {
        let start = Instant::now();
        let threads = if options.threads == 0 {
            rayon::current_num_threads()
        } else {
            options.threads
        };
        let config = Config {
            threads: threads as u32,
            // Warnings and errors come back through `Device::get_error`; no printing from
            // inside Embree.
            report_errors: false,
            ..Config::default()
        };
        // Creating a device sets FTZ/DAZ in the calling thread's MXCSR (the bindings follow
        // Embree's performance advice). That would change float results of everything else
        // later run on this thread, the native backend included, so create it on a thread of
        // its own.
        let device = std::thread::scope(|s| {
            s.spawn(|| Device::with_config(config))
                .join()
                .expect("embree device creation panicked")
        })
        .map_err(|e| EmbreeError(format!("rtcNewDevice failed: {e:?}")))?;
        let allocated = Arc::new(AtomicIsize::new(0));
        let counter = allocated.clone();
        device.set_memory_monitor_function(move |bytes, post| {
            // Pre-allocation calls (`post == false`) are followed by the allocation itself,
            // so count every call once; frees arrive as negative sizes.
            let _ = post;
            counter.fetch_add(bytes, Ordering::Relaxed);
            true
        });

        let mut flags = SceneFlags::NONE;
        if options.robust {
            flags |= SceneFlags::ROBUST;
        }
        if options.compact {
            flags |= SceneFlags::COMPACT;
        }
        let mut scene = device
            .create_scene()
            .map_err(|e| EmbreeError(format!("rtcNewScene failed: {e:?}")))?;
        scene.set_flags(flags);
        scene.set_build_quality(options.quality);

        let n = triangles.len();
        if n > 0 {
            if n > (u32::MAX / 3) as usize {
                return Err(EmbreeError(format!("{n} triangles is too many for Embree")));
            }
            let mut geometry = device
                .create_geometry(GeometryKind::TRIANGLE)
                .map_err(|e| EmbreeError(format!("rtcNewGeometry failed: {e:?}")))?;
            geometry.set_build_quality(options.quality);
            {
                let mut vertices = geometry
                    .set_new_buffer::<[f32; 3]>(BufferUsage::VERTEX, 0, Format::FLOAT3, 12, 3 * n)
                    .map_err(|e| EmbreeError(format!("vertex buffer: {e:?}")))?;
                for (dst, tri) in vertices.chunks_exact_mut(3).zip(&triangles.corners) {
                    for (d, p) in dst.iter_mut().zip(tri) {
                        *d = p.to_array();
                    }
                }
            }
            {
                let mut indices = geometry
                    .set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, n)
                    .map_err(|e| EmbreeError(format!("index buffer: {e:?}")))?;
                for (i, dst) in indices.iter_mut().enumerate() {
                    let k = 3 * i as u32;
                    *dst = [k, k + 1, k + 2];
                }
            }
            let geometry = geometry.commit();
            scene.attach_geometry(&geometry);
        }
        scene.commit();
        let error = device.get_error();
        if error != embree3::Error::NONE {
            return Err(EmbreeError(format!("rtcCommitScene failed: {error:?}")));
        }
        Ok(Self {
            scene,
            _device: device,
            ids: triangles.ids.clone(),
            allocated,
            options,
            build_seconds: start.elapsed().as_secs_f64(),
        })
    }

    pub fn options(&self) -> &EmbreeOptions {
        &self.options
    }

    /// Wall-clock seconds of the build (device creation, buffers and commit).
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Bytes Embree's memory monitor reports as allocated (BVH, triangle buffers, scratch
    /// left over), not counting the id map.
    pub fn embree_bytes(&self) -> usize {
        self.allocated.load(Ordering::Relaxed).max(0) as usize
    }

    #[inline]
    fn to_embree(ray: &Ray) -> embree3::Ray {
        embree3::Ray::segment(
            ray.origin.to_array(),
            ray.direction.to_array(),
            ray.t_min,
            ray.t_max,
        )
    }

    #[inline]
    fn to_hit(&self, rh: &RayHit) -> Option<Hit> {
        if rh.hit.geomID == INVALID_ID {
            return None;
        }
        let (instance, triangle) = self.ids[rh.hit.primID as usize];
        Some(Hit {
            t: rh.ray.tfar,
            u: rh.hit.u,
            v: rh.hit.v,
            instance,
            triangle,
        })
    }
}

impl Accel for EmbreeAccel {
    fn name(&self) -> &'static str {
        "embree"
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut ctx = IntersectContext::incoherent();
        let mut rh = RayHit::from_ray(Self::to_embree(ray));
        self.scene.intersect(&mut ctx, &mut rh);
        self.to_hit(&rh)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        let mut ctx = IntersectContext::incoherent();
        let mut r = Self::to_embree(ray);
        self.scene.occluded(&mut ctx, &mut r)
    }

    /// `rtcIntersect1M`: a stream of single rays, which Embree may repack into packets.
    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let mut ctx = IntersectContext::incoherent();
        let mut stream: Vec<RayHit> = rays
            .iter()
            .map(|r| RayHit::from_ray(Self::to_embree(r)))
            .collect();
        self.scene.intersect_stream_aos(&mut ctx, &mut stream);
        for (h, rh) in hits.iter_mut().zip(&stream) {
            *h = self.to_hit(rh);
        }
    }

    /// `rtcOccluded1M`.
    fn occluded_batch(&self, rays: &[Ray], occluded: &mut [bool]) {
        let mut ctx = IntersectContext::incoherent();
        let mut stream: Vec<embree3::Ray> = rays.iter().map(Self::to_embree).collect();
        self.scene.occluded_stream_aos(&mut ctx, &mut stream);
        for (o, r) in occluded.iter_mut().zip(&stream) {
            *o = r.tfar == f32::NEG_INFINITY;
        }
    }

    /// Embree's own allocations (from its memory monitor) plus the id map.
    fn memory_bytes(&self) -> usize {
        self.embree_bytes() + self.ids.len() * std::mem::size_of::<(u32, u32)>()
    }
}
