//! [`InstancedBvh`]: two-level instancing. One [`NativeBvh`] per mesh over its object-space
//! triangles, and a small binary BVH over the instances' world-space boxes on top. A ray is
//! carried into each candidate instance's object space with the inverse transform (direction
//! not normalised, so distances along the ray are the same in both spaces).

use glam::{Mat4, Vec3};
use pathlight_scene::Scene;

use crate::bvh::aabb::Aabb;
use crate::geometry::SceneTriangles;
use crate::native::NativeBvh;
use crate::ray::{Hit, Ray};
use crate::Accel;

/// Instances per top-level leaf.
const LEAF_SIZE: usize = 2;

/// A node of the top-level binary BVH: an inner node (`count == 0`, children at `first` and
/// `first + 1`) or a leaf of `count` entries of `order` from `first`.
#[derive(Debug, Clone, Copy)]
struct TopNode {
    bounds: Aabb,
    first: u32,
    count: u32,
}

/// An instance as the top level sees it.
#[derive(Debug, Clone, Copy)]
struct TopInstance {
    /// World to object.
    inverse: Mat4,
    /// Index into `InstancedBvh::meshes`.
    mesh: u32,
}

/// A two-level BVH: mesh BVHs shared by the instances that use them, under a BVH over
/// instance boxes.
pub struct InstancedBvh {
    /// One BVH per mesh that some instance uses (`None` for unused meshes).
    meshes: Vec<Option<NativeBvh>>,
    instances: Vec<TopInstance>,
    nodes: Vec<TopNode>,
    /// Instance indices, leaves refer to ranges of it.
    order: Vec<u32>,
    /// World-space triangles of instances whose transform can't be inverted (traced flat).
    singular: Option<NativeBvh>,
}

/// Slab test: the entry distance when the ray passes through `b` within
/// `[t_min, t_max]`. Conservative: NaN slabs (a zero direction component on a box face) are
/// ignored, and the exit distance is widened slightly against rounding.
#[inline]
fn slab(b: &Aabb, origin: Vec3, inv_dir: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let t0 = (b.min - origin) * inv_dir;
    let t1 = (b.max - origin) * inv_dir;
    let near = t0.min(t1);
    let far = t0.max(t1);
    let enter = near.max_element().max(t_min);
    let exit = far.min_element().min(t_max);
    let exit = exit + exit.abs() * (4.0 * f32::EPSILON);
    (enter <= exit).then_some(enter)
}

/// Grows a box by a small relative margin so that rounding in the transforms can't make the
/// top level miss geometry on its surface.
fn pad(b: Aabb) -> Aabb {
    if b.is_empty() {
        return b;
    }
    let scale = b.min.abs().max(b.max.abs()).max_element().max(1e-30);
    let m = Vec3::splat(scale * 1e-5);
    Aabb {
        min: b.min - m,
        max: b.max + m,
    }
}

/// Median-split build of node `node` over the instances in `order` (which starts at `offset`
/// of the whole order).
fn build_top(
    boxes: &[Aabb],
    order: &mut [u32],
    offset: usize,
    nodes: &mut Vec<TopNode>,
    node: usize,
) {
    let bounds = order
        .iter()
        .fold(Aabb::EMPTY, |a, &i| a.union(boxes[i as usize]));
    if order.len() <= LEAF_SIZE {
        nodes[node] = TopNode {
            bounds,
            first: offset as u32,
            count: order.len() as u32,
        };
        return;
    }
    let mut centroids = Aabb::EMPTY;
    for &i in order.iter() {
        centroids.grow(boxes[i as usize].center());
    }
    let extent = centroids.max - centroids.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        let ca = boxes[a as usize].center()[axis];
        let cb = boxes[b as usize].center()[axis];
        ca.total_cmp(&cb)
    });
    let left = nodes.len();
    nodes.push(TopNode {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    });
    nodes.push(TopNode {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    });
    nodes[node] = TopNode {
        bounds,
        first: left as u32,
        count: 0,
    };
    let (lo, hi) = order.split_at_mut(mid);
    build_top(boxes, lo, offset, nodes, left);
    build_top(boxes, hi, offset + mid, nodes, left + 1);
}

impl InstancedBvh {
    pub fn new(scene: &Scene) -> Self {
        let mut used = vec![false; scene.meshes.len()];
        for inst in &scene.instances {
            used[inst.mesh as usize] = true;
        }
        let mut mesh_boxes = vec![Aabb::EMPTY; scene.meshes.len()];
        let meshes: Vec<Option<NativeBvh>> = scene
            .meshes
            .iter()
            .enumerate()
            .map(|(m, mesh)| {
                if !used[m] {
                    return None;
                }
                let corners: Vec<[Vec3; 3]> =
                    (0..mesh.indices.len()).map(|t| mesh.triangle(t)).collect();
                for c in &corners {
                    mesh_boxes[m] = mesh_boxes[m].union(Aabb::of_triangle(c));
                }
                let ids = (0..corners.len() as u32).map(|t| (0, t)).collect();
                Some(NativeBvh::new(&SceneTriangles { corners, ids }))
            })
            .collect();

        let mut instances = Vec::with_capacity(scene.instances.len());
        let mut boxes = Vec::with_capacity(scene.instances.len());
        let mut singular = SceneTriangles::default();
        for (i, inst) in scene.instances.iter().enumerate() {
            let inverse = inst.transform.inverse();
            let ok = inst.transform.determinant() != 0.0
                && inverse.is_finite()
                && inst.transform.is_finite();
            let mb = mesh_boxes[inst.mesh as usize];
            let world = if ok && !mb.is_empty() {
                let mut w = Aabb::EMPTY;
                for k in 0..8 {
                    let p = Vec3::new(
                        if k & 1 == 0 { mb.min.x } else { mb.max.x },
                        if k & 2 == 0 { mb.min.y } else { mb.max.y },
                        if k & 4 == 0 { mb.min.z } else { mb.max.z },
                    );
                    w.grow(inst.transform.transform_point3(p));
                }
                pad(w)
            } else {
                Aabb::EMPTY
            };
            if !ok {
                let mesh = &scene.meshes[inst.mesh as usize];
                for t in 0..mesh.indices.len() {
                    let c = mesh.triangle(t).map(|p| inst.transform.transform_point3(p));
                    singular.corners.push(c);
                    singular.ids.push((i as u32, t as u32));
                }
            }
            instances.push(TopInstance {
                inverse,
                mesh: inst.mesh,
            });
            boxes.push(world);
        }

        // Only instances with geometry go into the top level.
        let mut order: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| !boxes[i as usize].is_empty())
            .collect();
        let mut nodes = Vec::new();
        if !order.is_empty() {
            nodes.push(TopNode {
                bounds: Aabb::EMPTY,
                first: 0,
                count: 0,
            });
            build_top(&boxes, &mut order, 0, &mut nodes, 0);
        }
        let singular = (!singular.is_empty()).then(|| NativeBvh::new(&singular));
        Self {
            meshes,
            instances,
            nodes,
            order,
            singular,
        }
    }

    /// Calls `visit` for each instance whose box the ray passes through, nearer boxes first,
    /// pruning boxes beyond the current `t_max` (which `visit` may lower). `visit` returns
    /// `true` to stop.
    #[inline]
    fn walk(&self, ray: &Ray, t_max: &mut f32, mut visit: impl FnMut(u32, &mut f32) -> bool) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = ray.direction.recip();
        let o = ray.origin;
        let mut stack: Vec<(u32, f32)> = Vec::with_capacity(32);
        let Some(t) = slab(&self.nodes[0].bounds, o, inv, ray.t_min, *t_max) else {
            return;
        };
        stack.push((0, t));
        while let Some((n, enter)) = stack.pop() {
            if enter > *t_max {
                continue;
            }
            let node = &self.nodes[n as usize];
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                for &i in &self.order[range] {
                    if visit(i, t_max) {
                        return;
                    }
                }
                continue;
            }
            let (a, b) = (node.first, node.first + 1);
            let ta = slab(&self.nodes[a as usize].bounds, o, inv, ray.t_min, *t_max);
            let tb = slab(&self.nodes[b as usize].bounds, o, inv, ray.t_min, *t_max);
            match (ta, tb) {
                (Some(x), Some(y)) => {
                    // Push the farther one first so the nearer is visited next.
                    if x <= y {
                        stack.push((b, y));
                        stack.push((a, x));
                    } else {
                        stack.push((a, x));
                        stack.push((b, y));
                    }
                }
                (Some(x), None) => stack.push((a, x)),
                (None, Some(y)) => stack.push((b, y)),
                (None, None) => {}
            }
        }
    }

    #[inline]
    fn local_ray(&self, inst: &TopInstance, ray: &Ray, t_max: f32) -> Ray {
        Ray {
            origin: inst.inverse.transform_point3(ray.origin),
            direction: inst.inverse.transform_vector3(ray.direction),
            t_min: ray.t_min,
            t_max,
        }
    }
}

impl Accel for InstancedBvh {
    fn name(&self) -> &'static str {
        "native-instanced"
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut best = self.singular.as_ref().and_then(|s| s.intersect(ray));
        let mut t_max = best.map_or(ray.t_max, |h| h.t);
        self.walk(ray, &mut t_max, |i, t_max| {
            let inst = &self.instances[i as usize];
            if let Some(bvh) = &self.meshes[inst.mesh as usize] {
                let local = self.local_ray(inst, ray, *t_max);
                if let Some(mut h) = bvh.intersect(&local) {
                    h.instance = i;
                    *t_max = h.t;
                    best = Some(h);
                }
            }
            false
        });
        best
    }

    fn occluded(&self, ray: &Ray) -> bool {
        if self.singular.as_ref().is_some_and(|s| s.occluded(ray)) {
            return true;
        }
        let mut hit = false;
        let mut t_max = ray.t_max;
        self.walk(ray, &mut t_max, |i, t_max| {
            let inst = &self.instances[i as usize];
            if let Some(bvh) = &self.meshes[inst.mesh as usize] {
                hit = bvh.occluded(&self.local_ray(inst, ray, *t_max));
            }
            hit
        });
        hit
    }

    fn memory_bytes(&self) -> usize {
        self.meshes
            .iter()
            .flatten()
            .chain(self.singular.as_ref())
            .map(|b| b.memory_bytes())
            .sum::<usize>()
            + self.instances.len() * std::mem::size_of::<TopInstance>()
            + self.nodes.len() * std::mem::size_of::<TopNode>()
            + self.order.len() * std::mem::size_of::<u32>()
    }
}
