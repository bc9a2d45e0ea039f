//! The floor of a frame: the rays an acceleration structure is asked to trace, recorded as
//! they are asked for ([`Recorder`]), then traced again alone ([`Recording::replay`]). What
//! the replay takes is what the frame's rays cost without anything around them: the time a
//! frame could not go below with this structure, against which the rest of the frame is
//! judged (`pathlight bench frame`).
//!
//! Each worker thread records into a log of its own (by its index in the current rayon pool),
//! in the order it traced; the replay traces each thread's log on one thread of the pool, the
//! logs in parallel, one kind of query at a time (camera batches, closest hits, shadow rays),
//! with the same calls (a batch stays a batch).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use rayon::prelude::*;

use crate::ray::{Hit, Ray};
use crate::Accel;

/// A kind of query to the structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Query {
    /// [`Accel::intersect_batch`]: camera rays, as packets where coherent.
    ClosestBatch,
    /// [`Accel::intersect`]: one closest-hit ray (bounces).
    Closest,
    /// [`Accel::occluded`] and [`Accel::occluded_batch`]: shadow rays.
    Occluded,
}

impl Query {
    pub const ALL: [Query; 3] = [Query::ClosestBatch, Query::Closest, Query::Occluded];

    pub fn name(self) -> &'static str {
        match self {
            Query::ClosestBatch => "primary",
            Query::Closest => "closest",
            Query::Occluded => "shadow",
        }
    }
}

/// One thread's calls, in order: each call's query and its number of rays (1 but for
/// batches), and the rays one after the other.
#[derive(Debug, Default, Clone)]
struct Log {
    calls: Vec<(Query, u32)>,
    rays: Vec<Ray>,
}

impl Log {
    fn push(&mut self, query: Query, rays: &[Ray]) {
        self.calls.push((query, rays.len() as u32));
        self.rays.extend_from_slice(rays);
    }
}

/// An acceleration structure that records every ray it traces, and traces it with the
/// structure it wraps ([`Recorder::install`]).
pub struct Recorder {
    inner: Arc<dyn Accel>,
    logs: Arc<Logs>,
}

/// One log per thread of the pool the recorder was installed on, and one for threads outside
/// it.
type Logs = Vec<Mutex<Log>>;

/// The other end of an installed [`Recorder`]: what it recorded, and the structure it wraps.
pub struct Tap {
    inner: Arc<dyn Accel>,
    logs: Arc<Logs>,
}

impl Recorder {
    /// Puts a recorder around the structure in `slot` (e.g. `World::accel`), recording on the
    /// current rayon pool's threads from now on: the returned [`Tap`] takes what it recorded.
    pub fn install(slot: &mut Box<dyn Accel>) -> Tap {
        let inner: Arc<dyn Accel> = Arc::from(std::mem::replace(slot, Box::new(Nothing)));
        let logs: Arc<Logs> = Arc::new(
            (0..rayon::current_num_threads() + 1)
                .map(|_| Mutex::default())
                .collect(),
        );
        *slot = Box::new(Recorder {
            inner: inner.clone(),
            logs: logs.clone(),
        });
        Tap { inner, logs }
    }

    fn record(&self, query: Query, rays: &[Ray]) {
        let slot = rayon::current_thread_index().map_or(0, |i| i + 1) % self.logs.len();
        let mut log = self.logs[slot].lock().unwrap_or_else(|e| e.into_inner());
        log.push(query, rays);
    }
}

impl Tap {
    /// What was recorded since the last call (the logs are emptied).
    pub fn take(&self) -> Recording {
        let logs = self
            .logs
            .iter()
            .map(|l| std::mem::take(&mut *l.lock().unwrap_or_else(|e| e.into_inner())))
            .filter(|l| !l.calls.is_empty())
            .collect();
        Recording { logs }
    }

    /// The structure the recorder wraps (to replay through).
    pub fn accel(&self) -> &dyn Accel {
        &*self.inner
    }
}

impl Accel for Recorder {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.record(Query::Closest, std::slice::from_ref(ray));
        self.inner.intersect(ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.record(Query::Occluded, std::slice::from_ref(ray));
        self.inner.occluded(ray)
    }

    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.record(Query::ClosestBatch, rays);
        self.inner.intersect_batch(rays, hits)
    }

    fn occluded_batch(&self, rays: &[Ray], occluded: &mut [bool]) {
        // Shadow rays in batches are shadow rays: one kind in the floor.
        self.record(Query::Occluded, rays);
        self.inner.occluded_batch(rays, occluded)
    }

    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }
}

/// The rays a [`Recorder`] saw, by thread.
#[derive(Debug, Default, Clone)]
pub struct Recording {
    logs: Vec<Log>,
}

impl Recording {
    /// Rays of kind `query` (all kinds: `None`).
    pub fn rays(&self, query: Option<Query>) -> u64 {
        self.logs
            .iter()
            .flat_map(|l| &l.calls)
            .filter(|(q, _)| query.is_none_or(|k| k == *q))
            .map(|&(_, n)| n as u64)
            .sum()
    }

    /// Traces the recorded rays of kind `query` again through `accel`, each thread's log on a
    /// thread of the current pool, in parallel: the wall time in milliseconds.
    pub fn replay(&self, accel: &dyn Accel, query: Query) -> f64 {
        let start = Instant::now();
        let found: u64 = self
            .logs
            .par_iter()
            .with_max_len(1)
            .map(|log| replay_log(accel, log, query))
            .sum();
        std::hint::black_box(found);
        start.elapsed().as_secs_f64() * 1e3
    }
}

/// Traces `log`'s calls of kind `query` through `accel`; returns the hits found (so that the
/// work is not optimised away).
fn replay_log(accel: &dyn Accel, log: &Log, query: Query) -> u64 {
    let mut found = 0u64;
    let mut at = 0usize;
    let mut hits: Vec<Option<Hit>> = Vec::new();
    for &(q, n) in &log.calls {
        let rays = &log.rays[at..at + n as usize];
        at += n as usize;
        if q != query {
            continue;
        }
        match q {
            Query::ClosestBatch => {
                hits.clear();
                hits.resize(rays.len(), None);
                accel.intersect_batch(rays, &mut hits);
                found += hits.iter().filter(|h| h.is_some()).count() as u64;
            }
            Query::Closest => found += accel.intersect(&rays[0]).is_some() as u64,
            Query::Occluded => {
                for r in rays {
                    found += accel.occluded(r) as u64;
                }
            }
        }
    }
    found
}

/// An empty structure, standing in while a [`Recorder`] is put in place.
struct Nothing;

impl Accel for Nothing {
    fn name(&self) -> &'static str {
        "nothing"
    }
    fn intersect(&self, _: &Ray) -> Option<Hit> {
        None
    }
    fn occluded(&self, _: &Ray) -> bool {
        false
    }
    fn memory_bytes(&self) -> usize {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brute::BruteForce;
    use crate::geometry::SceneTriangles;
    use glam::Vec3;

    /// A square of side 2 at z = 0, as two triangles.
    fn square() -> Box<dyn Accel> {
        let (a, b, c, d) = (
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        );
        Box::new(BruteForce::new(SceneTriangles {
            corners: vec![[a, b, c], [a, c, d]],
            ids: vec![(0, 0), (0, 1)],
        }))
    }

    fn down(x: f32) -> Ray {
        Ray::new(Vec3::new(x, 0.0, 1.0), Vec3::NEG_Z)
    }

    /// Every call is recorded with its kind and rays, answered by the wrapped structure, and
    /// the replay traces the same rays (the hits it finds are the calls' own).
    #[test]
    fn records_every_call_and_replays_it() {
        let mut slot = square();
        let tap = Recorder::install(&mut slot);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        // Outside the pool, then on its threads.
        assert!(slot.intersect(&down(0.5)).is_some());
        assert!(!slot.occluded(&down(3.0)));
        pool.install(|| {
            (0..100).into_par_iter().for_each(|i| {
                let x = i as f32 / 25.0 - 2.0;
                let mut hits = [None; 3];
                slot.intersect_batch(&[down(x), down(x), down(0.0)], &mut hits);
                assert_eq!(hits[0].is_some(), x.abs() <= 1.0);
                let mut occluded = [false; 2];
                slot.occluded_batch(&[down(x), down(5.0)], &mut occluded);
                assert_eq!(occluded, [x.abs() <= 1.0, false]);
            })
        });
        let recording = tap.take();
        assert_eq!(recording.rays(None), 2 + 100 * 5);
        assert_eq!(recording.rays(Some(Query::ClosestBatch)), 300);
        assert_eq!(recording.rays(Some(Query::Closest)), 1);
        assert_eq!(recording.rays(Some(Query::Occluded)), 1 + 200);
        // The replay finds what the calls found: 51 of the 100 x values are on the square.
        let found = |q| {
            (recording.logs.iter())
                .map(|l| replay_log(tap.accel(), l, q))
                .sum::<u64>()
        };
        assert_eq!(found(Query::ClosestBatch), 2 * 51 + 100);
        assert_eq!(found(Query::Closest), 1);
        assert_eq!(found(Query::Occluded), 51);
        assert!(pool.install(|| recording.replay(tap.accel(), Query::Occluded)) >= 0.0);
        // Taken: the logs start again empty.
        assert_eq!(tap.take().rays(None), 0);
        assert_eq!(slot.name(), "brute");
    }
}
