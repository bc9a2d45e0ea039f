//! The native BVH: a binned SAH binary build ([`build`]), collapsed to four children per node
//! ([`wide`]), traversed one ray at a time with SIMD box and triangle tests ([`traverse`]) or
//! eight coherent rays at a time ([`packet`]).

pub(crate) mod aabb;
pub(crate) mod build;
pub(crate) mod packet;
pub(crate) mod traverse;
pub(crate) mod wide;
