//! The texture cache's unit tests: the tables' protocol, the blocks, and the filter's window.

use std::sync::atomic::{AtomicU32, Ordering};

use glam::UVec2;
use pathlight_core::rng::hash;

use super::table::{Block, Claim, Table, BLOCK, CELLS, READY, SQUARES, STATE, WAYS};
use super::texels::convolve;

/// Keys that land in one set (a table of one set).
fn keys(n: u64) -> Vec<u64> {
    (1..=n).map(|k| (hash(&[k]) | 4) & !STATE).collect()
}

fn publish_all(t: &Table, keys: &[u64], frame: u32) -> Vec<usize> {
    keys.iter()
        .map(|&k| match t.claim(k, frame) {
            Claim::Mine(i, _) => {
                t.write(i, &[k as f32]);
                t.publish(i, k, frame);
                i
            }
            _ => panic!("{k:x} not claimed"),
        })
        .collect()
}

/// The window's filters on a grid of squares holding a linear ramp (one channel, each
/// square weight 1 or, past a triangle's edge, empty): the weighted mean is the ramp's
/// value where the window is whole and biased where an edge cuts it (toward the side that
/// has squares); the linear regression gives the ramp's value exactly in both.
#[test]
fn the_regression_follows_a_gradient_to_the_window_s_edge() {
    let (w, lo, ch) = (10usize, 4usize, 1usize);
    let ramp = |x: usize, y: usize| 1.0 + 0.25 * x as f32 + 0.125 * y as f32;
    let weights: Vec<f32> = (-3i32..=3)
        .map(|d| (-(d * d) as f32 / (2.0 * 1.75f32.powi(2))).exp())
        .collect();
    // Whole, then cut: no squares left of column 4 (the block's left squares on the edge).
    for cut in [0usize, lo] {
        let mut grid = vec![0.0f32; w * w * (ch + 1)];
        for y in 0..w {
            for x in cut..w {
                grid[(y * w + x) * 2] = ramp(x, y);
                grid[(y * w + x) * 2 + 1] = 1.0;
            }
        }
        let mut rows = Vec::new();
        let (mut mean, mut linear) = ([0.0f32; SQUARES], [0.0f32; SQUARES]);
        convolve(&grid, w, lo, &weights, ch, 0, &mut rows, &mut mean);
        convolve(&grid, w, lo, &weights, ch, 2, &mut rows, &mut linear);
        for s in 0..SQUARES {
            let exact = ramp(lo + s % 2, lo + s / 2);
            let (bias, error) = ((mean[s] - exact).abs(), (linear[s] - exact).abs());
            if cut == 0 {
                assert!(bias < 1e-4 * exact, "whole window, square {s}: {}", mean[s]);
                assert!(
                    error < 1e-4 * exact,
                    "whole window, square {s}: {}",
                    linear[s]
                );
            } else if s % 2 == 0 {
                // (The regression's slopes are damped a little: not exact at the edge.)
                assert!(
                    bias > 0.05 * exact,
                    "cut, square {s}: {} (no bias)",
                    mean[s]
                );
                assert!(
                    error < bias / 4.0,
                    "cut, square {s}: {} against {exact} (the mean's {})",
                    linear[s],
                    mean[s]
                );
            }
        }
    }
}

/// Colliding keys are told apart by their tags: each reads its own data; at the next
/// frame a new key takes the way shaded longest ago while the others keep their data; a
/// set full of this frame's keys gives one of their ways to a new key (a table too small
/// for its frame), and its readers see it go; a set whose ways are all being shaded turns
/// a new key away.
#[test]
fn tags_catch_colliding_keys() {
    let t = Table::new(1, 1);
    assert_eq!(t.slots(), WAYS);
    let k = keys(WAYS as u64 + 2);
    let slots = publish_all(&t, &k[..WAYS], 1);
    for (&key, &i) in k.iter().zip(&slots) {
        match t.claim(key, 1) {
            Claim::Ready(j, s) => {
                assert_eq!(j, i);
                assert_eq!(t.word(j, 0), key as f32);
                assert!(t.still(j, s, 1));
            }
            _ => panic!("{key:x} not ready"),
        }
    }
    // Frame 2: k[0] shaded again on its history; the new key takes the oldest way.
    match t.claim(k[0], 2) {
        Claim::Mine(i, fresh) => {
            assert!(!fresh);
            assert_eq!(t.word(i, 0), k[0] as f32, "its history kept");
            t.publish(i, k[0], 2)
        }
        _ => panic!("not claimed again"),
    }
    let taken = match t.claim(k[WAYS], 2) {
        Claim::Mine(i, fresh) => {
            assert!(fresh);
            assert_ne!(i, slots[0], "not the way shaded this frame");
            t.publish(i, k[WAYS], 2);
            i
        }
        _ => panic!("not claimed"),
    };
    assert!(matches!(t.claim(k[2], 2), Claim::Mine(_, false)) || slots[2] == taken);
    // Frame 3: every way shaded this frame, then one more key.
    let t = Table::new(1, 1);
    let slots = publish_all(&t, &k[..WAYS], 3);
    let (i0, s0) = match t.claim(k[0], 3) {
        Claim::Ready(i, s) => (i, s),
        _ => panic!("not ready"),
    };
    match t.claim(k[WAYS], 3) {
        Claim::Mine(i, true) => {
            t.write(i, &[1.5]);
            t.publish(i, k[WAYS], 3);
            let gone = slots.iter().position(|&j| j == i).unwrap();
            if i == i0 {
                assert!(
                    !t.still(i0, s0, 3),
                    "the reader of the replaced key sees it go"
                );
            }
            assert!(matches!(t.claim(k[gone], 3), Claim::Mine(_, true)));
        }
        _ => panic!("the new key found no way"),
    }
    // Every way being shaded: a new key is turned away.
    let busy = Table::new(1, 1);
    for &key in &k[..WAYS] {
        assert!(matches!(busy.claim(key, 1), Claim::Mine(..)));
    }
    assert!(matches!(busy.claim(k[WAYS + 1], 1), Claim::Full));
}

/// A set full of this frame's keys gives its ways up first in, first out: each new key
/// takes the way filled longest ago, and the keys just put in stay (a set that gave up
/// the same way every time would drop each new key at the next).
#[test]
fn a_full_set_gives_up_its_oldest_keys_first() {
    let t = Table::new(1, 1);
    let k = keys(WAYS as u64 + 3);
    let slots = publish_all(&t, &k[..WAYS], 1);
    for (n, &key) in k[WAYS..].iter().enumerate() {
        match t.claim(key, 1) {
            Claim::Mine(i, true) => {
                assert_eq!(i, slots[n], "key {n} past the set's ways");
                t.publish(i, key, 1);
            }
            _ => panic!("no way for key {n} past the set's ways"),
        }
    }
    // (The newest first: claiming a key that went puts it back, giving up another.)
    for (n, &key) in k.iter().enumerate().rev() {
        let ready = matches!(t.claim(key, 1), Claim::Ready(..));
        assert_eq!(ready, n >= 3, "key {n}");
    }
}

/// Two threads claiming the same keys of one frame: each key is claimed once, and ends in
/// exactly one way.
#[test]
fn each_key_is_claimed_once_per_frame_by_two_threads() {
    // A table large enough for the frame (no set overflows).
    let t = Table::new(1 << 20, 1);
    let k = keys(2000);
    for frame in 1..4 {
        let claimed: Vec<AtomicU32> = k.iter().map(|_| AtomicU32::new(0)).collect();
        std::thread::scope(|s| {
            for _ in 0..2 {
                s.spawn(|| {
                    for (n, &key) in k.iter().enumerate() {
                        loop {
                            match t.claim(key, frame) {
                                Claim::Mine(i, _) => {
                                    claimed[n].fetch_add(1, Ordering::Relaxed);
                                    t.publish(i, key, frame);
                                    break;
                                }
                                Claim::Ready(..) | Claim::Full => break,
                                Claim::Busy => std::hint::spin_loop(),
                            }
                        }
                    }
                });
            }
        });
        let full = claimed
            .iter()
            .filter(|c| c.load(Ordering::Relaxed) == 0)
            .count();
        assert!(claimed.iter().all(|c| c.load(Ordering::Relaxed) <= 1));
        let ways = (0..t.slots())
            .filter(|&i| t.states[i].load(Ordering::Relaxed) & STATE == READY)
            .filter(|&i| t.frames[i].load(Ordering::Relaxed) == frame)
            .count();
        assert_eq!(ways + full, k.len(), "frame {frame}");
    }
}

/// A block's cells lie in the triangle, and its neighbours beyond the triangle are none.
#[test]
fn blocks_hold_the_triangles_cells() {
    let b = Block {
        instance: 0,
        triangle: 0,
        back: false,
        level: 0,
        at: UVec2::ZERO,
        resolution: 3,
    };
    let inside = (0..CELLS).filter(|&k| b.cell(k).is_some()).count();
    // A grid of 3: 9 cells, of which those in the block's first BLOCK x BLOCK squares.
    let want = (0..3u32)
        .flat_map(|y| (0..3u32).map(move |x| (x, y)))
        .filter(|&(x, y)| x < BLOCK && y < BLOCK)
        .map(|(x, y)| u32::from(x + y < 3) + u32::from(x + y + 1 < 3))
        .sum::<u32>();
    assert_eq!(inside as u32, want);
    assert!(b.beside(-1, 0).is_none());
    assert!(b.beside(3, 0).is_none());
}
