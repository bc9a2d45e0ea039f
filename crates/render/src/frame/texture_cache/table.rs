//! The texture cache's tables: fixed tables of slots in sets of eight ways, each slot a block
//! of cells' or texels' data under its key, and the protocol by which the lighting pass's
//! threads find, claim, shade and publish them (the paper's three states: empty, being shaded,
//! shaded at a frame), without a lock on a read. The module doc of [`super`] tells why blocks,
//! eight ways and first in, first out.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};

use glam::UVec2;
use pathlight_core::rng::hash;

use super::surface_grid::Cell;

/// Squares along a block's side.
pub(super) const BLOCK: u32 = 2;
/// Squares in a block.
pub(super) const SQUARES: usize = (BLOCK * BLOCK) as usize;
/// Cells in a block (each square's two halves).
pub(super) const CELLS: usize = 2 * SQUARES;
/// Ways per set.
pub(super) const WAYS: usize = 8;

/// A slot's state, in the low two bits of its state word (the rest is the key).
const EMPTY: u64 = 0;
const BUSY: u64 = 1;
pub(super) const READY: u64 = 2;
pub(super) const STATE: u64 = 3;

/// A block of [`BLOCK`] x [`BLOCK`] squares of one side of one triangle's grid at one level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Block {
    pub(super) instance: u32,
    pub(super) triangle: u32,
    pub(super) back: bool,
    pub(super) level: u8,
    /// The block's place among the grid's blocks.
    pub(super) at: UVec2,
    /// Squares along the triangle's edge at this level.
    pub(super) resolution: u32,
}

impl Block {
    /// The block of `cell` (of a grid `resolution` squares along), and the cell's index in it.
    pub(super) fn of(cell: &Cell, resolution: u32) -> (Block, usize) {
        let at = cell.square / BLOCK;
        let local = cell.square % BLOCK;
        let square = (local.y * BLOCK + local.x) as usize;
        (
            Block {
                instance: cell.instance,
                triangle: cell.triangle,
                back: cell.back,
                level: cell.level,
                at,
                resolution,
            },
            2 * square + cell.upper as usize,
        )
    }

    /// The table key: a hash of everything that names the block (Eq. 3 over blocks), never
    /// zero, its state bits clear.
    pub(super) fn key(&self) -> u64 {
        let c = Cell {
            instance: self.instance,
            triangle: self.triangle,
            back: self.back,
            level: self.level,
            square: self.at,
            upper: false,
        };
        (c.key() | 4) & !STATE
    }

    /// The key of the texel of cell `k` of the block (its place, Eq. 3 over texels).
    pub(super) fn texel_key(&self, k: usize) -> u64 {
        hash(&[self.key(), k as u64])
    }

    /// The neighbouring block `d` blocks away, if it holds any square of the triangle.
    pub(super) fn beside(&self, dx: i32, dy: i32) -> Option<Block> {
        let (x, y) = (self.at.x as i32 + dx, self.at.y as i32 + dy);
        let r = self.resolution as i32;
        (x >= 0 && y >= 0 && (x + y) * (BLOCK as i32) < r).then_some(Block {
            at: UVec2::new(x as u32, y as u32),
            ..*self
        })
    }

    /// The cell with index `k` in the block, if it lies in the triangle.
    pub(super) fn cell(&self, k: usize) -> Option<Cell> {
        let square = (k / 2) as u32;
        let upper = k % 2 == 1;
        let s = self.at * BLOCK + UVec2::new(square % BLOCK, square / BLOCK);
        let r = self.resolution;
        let inside = if upper {
            s.x + s.y + 1 < r
        } else {
            s.x + s.y < r
        };
        inside.then_some(Cell {
            instance: self.instance,
            triangle: self.triangle,
            back: self.back,
            level: self.level,
            square: s,
            upper,
        })
    }
}

/// A fixed table of slots in sets of [`WAYS`], each slot a state word (key and state), the
/// frame it was shaded at, and `stride` words of data.
#[derive(Default)]
pub(super) struct Table {
    pub(super) states: Vec<AtomicU64>,
    pub(super) frames: Vec<AtomicU32>,
    /// Per set: a thread is putting a new key in it.
    inserting: Vec<AtomicBool>,
    /// Per set (under its insertion flag): the way after the last of this frame's blocks it
    /// gave up, where it looks first for the next (first in, first out).
    turn: Vec<AtomicU32>,
    data: Vec<AtomicU32>,
    pub(super) stride: usize,
}

/// What a thread found for a key.
pub(super) enum Claim {
    /// Shaded this frame, at this slot.
    /// (With its state word, to check after reading that the slot still holds it:
    /// [`Table::still`].)
    Ready(usize, u64),
    /// Claimed by this thread, to be shaded (`fresh`: a new key, its data to be cleared).
    Mine(usize, bool),
    /// Being shaded by another thread.
    Busy,
    /// Its set is full of this frame's keys.
    Full,
}

impl Table {
    /// A table of `bytes` bytes of slots of `stride` data words.
    pub(super) fn new(bytes: usize, stride: usize) -> Self {
        let slot = 12 + 4 * stride;
        let sets = (bytes / (slot * WAYS)).max(1);
        let n = sets * WAYS;
        Self {
            states: (0..n).map(|_| AtomicU64::new(EMPTY)).collect(),
            frames: (0..n).map(|_| AtomicU32::new(0)).collect(),
            inserting: (0..sets).map(|_| AtomicBool::new(false)).collect(),
            turn: (0..sets).map(|_| AtomicU32::new(0)).collect(),
            data: (0..n * stride).map(|_| AtomicU32::new(0)).collect(),
            stride,
        }
    }

    pub(super) fn slots(&self) -> usize {
        self.states.len()
    }

    pub(super) fn bytes(&self) -> usize {
        self.slots() * 12 + self.inserting.len() * 5 + self.data.len() * 4
    }

    /// Every slot empty.
    pub(super) fn clear(&self) {
        for s in &self.states {
            s.store(EMPTY, Ordering::Relaxed);
        }
    }

    /// The first slot of `key`'s set.
    fn set(&self, key: u64) -> usize {
        let sets = self.inserting.len() as u64;
        ((key >> 2).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) as usize % sets as usize * WAYS
    }

    /// The slot of `key` in its set and its state word, if there.
    fn find(&self, key: u64, base: usize) -> Option<(usize, u64)> {
        (base..base + WAYS).find_map(|i| {
            let s = self.states[i].load(Ordering::Acquire);
            (s & !STATE == key).then_some((i, s))
        })
    }

    /// Finds or claims `key` for frame `frame` (the three-state protocol).
    pub(super) fn claim(&self, key: u64, frame: u32) -> Claim {
        let base = self.set(key);
        loop {
            if let Some((i, s)) = self.find(key, base) {
                match s & STATE {
                    BUSY => return Claim::Busy,
                    // (The state re-read: the slot was not taken by another key meanwhile.)
                    READY
                        if self.frames[i].load(Ordering::Acquire) == frame
                            && self.states[i].load(Ordering::Acquire) == s =>
                    {
                        return Claim::Ready(i, s)
                    }
                    // Shaded at an earlier frame: re-shade it on its history. (The state word
                    // is the same before and after another thread re-shades it: having taken
                    // it, check that this frame did not.)
                    _ => match self.states[i].compare_exchange(
                        s,
                        key | BUSY,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    ) {
                        Ok(_) if self.frames[i].load(Ordering::Acquire) == frame => {
                            self.states[i].store(s, Ordering::Release);
                            continue;
                        }
                        Ok(_) => return Claim::Mine(i, false),
                        Err(_) => continue,
                    },
                }
            }
            // A new key: under the set's insertion flag, so that two threads never put the
            // same key in two ways.
            let flag = &self.inserting[base / WAYS];
            if flag
                .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
                .is_err()
            {
                std::hint::spin_loop();
                continue;
            }
            if self.find(key, base).is_some() {
                flag.store(false, Ordering::Release);
                continue;
            }
            // An empty way, else the way shaded longest ago, else (the set full of this
            // frame's blocks: a table too small for the frame) the one of this frame's that
            // came in first, whose readers see it go (`still`) and look again: a block shaded
            // once is then reused by the lookups that follow it instead of every lookup
            // shading it again, and the lighting pass's order (down columns of the image)
            // gives up the blocks it has gone past.
            let turn = &self.turn[base / WAYS];
            let first = turn.load(Ordering::Relaxed) as usize;
            let victim = (base..base + WAYS)
                .filter_map(|i| {
                    let s = self.states[i].load(Ordering::Acquire);
                    match s & STATE {
                        EMPTY => Some((i, s, (false, 0, 0))),
                        READY => {
                            // (This frame's last, from the set's turn on; then the smaller
                            // `f - frame`, wrapping: the older.)
                            let f = self.frames[i].load(Ordering::Acquire);
                            let order = (i - base + WAYS - first) % WAYS;
                            Some((i, s, (f == frame, f.wrapping_sub(frame), order)))
                        }
                        _ => None,
                    }
                })
                .min_by_key(|&(_, _, age)| age);
            if let Some((i, _, (true, _, _))) = victim {
                turn.store(((i - base + 1) % WAYS) as u32, Ordering::Relaxed);
            }
            let claim = match victim {
                None => Claim::Full,
                Some((i, s, (current, _, _))) => {
                    match self.states[i].compare_exchange(
                        s,
                        key | BUSY,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    ) {
                        // A stale way that its key re-shaded this frame meanwhile: keep it.
                        Ok(_) if !current && self.frames[i].load(Ordering::Acquire) == frame => {
                            self.states[i].store(s, Ordering::Release);
                            flag.store(false, Ordering::Release);
                            continue;
                        }
                        Ok(_) => Claim::Mine(i, true),
                        // Re-shaded meanwhile by its own key's thread: look again.
                        Err(_) => {
                            flag.store(false, Ordering::Release);
                            continue;
                        }
                    }
                }
            };
            flag.store(false, Ordering::Release);
            return claim;
        }
    }

    /// After reading slot `i`, found shaded at `frame` with state word `s`: it still is (no
    /// other key took it while it was read; a seqlock's second check).
    pub(super) fn still(&self, i: usize, s: u64, frame: u32) -> bool {
        std::sync::atomic::fence(Ordering::Acquire);
        self.states[i].load(Ordering::Relaxed) == s
            && self.frames[i].load(Ordering::Relaxed) == frame
    }

    /// Publishes slot `i`, claimed for `key`, as shaded at `frame`.
    pub(super) fn publish(&self, i: usize, key: u64, frame: u32) {
        self.frames[i].store(frame, Ordering::Release);
        self.states[i].store(key | READY, Ordering::Release);
    }

    pub(super) fn word(&self, i: usize, k: usize) -> f32 {
        f32::from_bits(self.data[i * self.stride + k].load(Ordering::Relaxed))
    }

    fn set_word(&self, i: usize, k: usize, v: f32) {
        self.data[i * self.stride + k].store(v.to_bits(), Ordering::Relaxed)
    }

    /// Slot `i`'s data.
    pub(super) fn read(&self, i: usize, out: &mut [f32]) {
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.word(i, k);
        }
    }

    /// Writes slot `i`'s data.
    pub(super) fn write(&self, i: usize, values: &[f32]) {
        for (k, &v) in values.iter().enumerate() {
            self.set_word(i, k, v);
        }
    }
}
