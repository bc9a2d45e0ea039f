//! Accessors: typed views of buffer data, read with every offset, stride and count checked
//! before anything is allocated. Sparse accessors are applied. Integer components are
//! converted to `f32`, normalised when the accessor says so (or when the caller requires it,
//! as `KHR_mesh_quantization` does for texture coordinates and colours).

use std::path::Path;

use ::gltf::json;
use json::accessor::{ComponentType, Type};
use json::validation::Checked;

use super::buffer::Buffers;
use crate::error::{Result, SceneError};

/// Reads accessors of one document.
pub struct AccessorReader<'a> {
    pub root: &'a json::Root,
    pub buffers: &'a Buffers,
    pub file: &'a Path,
    /// Largest element count accepted (bounds allocation).
    pub max_count: u64,
}

fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn dimension(t: Type) -> usize {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// One component at `bytes[0..size]`, as `f32`.
#[inline]
fn component(bytes: &[u8], c: ComponentType, normalized: bool) -> f32 {
    match c {
        ComponentType::F32 => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
        ComponentType::U8 => {
            let v = bytes[0] as f32;
            if normalized {
                v / 255.0
            } else {
                v
            }
        }
        ComponentType::I8 => {
            let v = bytes[0] as i8 as f32;
            if normalized {
                (v / 127.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes([bytes[0], bytes[1]]) as f32;
            if normalized {
                v / 65535.0
            } else {
                v
            }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes([bytes[0], bytes[1]]) as f32;
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        ComponentType::U32 => {
            let v = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f32;
            if normalized {
                v / 4_294_967_295.0
            } else {
                v
            }
        }
    }
}

#[inline]
fn index_component(bytes: &[u8], c: ComponentType) -> Option<u32> {
    match c {
        ComponentType::U8 => Some(bytes[0] as u32),
        ComponentType::U16 => Some(u16::from_le_bytes([bytes[0], bytes[1]]) as u32),
        ComponentType::U32 => Some(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])),
        _ => None,
    }
}

/// Where the elements of an accessor (or a sparse part) lie.
struct Layout<'b> {
    bytes: &'b [u8],
    stride: usize,
    elem: usize,
}

impl<'a> AccessorReader<'a> {
    fn err(&self, index: usize, what: impl std::fmt::Display) -> SceneError {
        SceneError::new(self.file, format!("accessor {index}: {what}"))
    }

    fn accessor(&self, index: usize) -> Result<&'a json::Accessor> {
        self.root
            .accessors
            .get(index)
            .ok_or_else(|| self.err(index, "does not exist"))
    }

    /// Checks that `count` elements of `elem` bytes at `offset` with `stride` fit in view
    /// `view`, and returns their bytes.
    fn layout(
        &self,
        index: usize,
        view: usize,
        offset: u64,
        count: u64,
        elem: usize,
        strided: bool,
    ) -> Result<Layout<'a>> {
        let bytes = self.buffers.view(self.root, view, self.file)?;
        let stride = match self.root.buffer_views.get(view).and_then(|v| v.byte_stride) {
            Some(s) if strided => s.0,
            _ => elem,
        };
        if stride < elem {
            return Err(self.err(
                index,
                format!("byteStride {stride} is smaller than one element ({elem} bytes)"),
            ));
        }
        let needed = if count == 0 {
            Some(0)
        } else {
            (count - 1)
                .checked_mul(stride as u64)
                .and_then(|n| n.checked_add(elem as u64))
                .and_then(|n| n.checked_add(offset))
        };
        match needed {
            Some(n) if n <= bytes.len() as u64 => Ok(Layout {
                bytes: &bytes[offset as usize..],
                stride,
                elem,
            }),
            _ => Err(self.err(
                index,
                format!(
                    "{count} elements of {elem} bytes (stride {stride}) from offset {offset} do not fit in bufferView {view} ({} bytes)",
                    bytes.len()
                ),
            )),
        }
    }

    fn checked_count(&self, index: usize, count: u64) -> Result<usize> {
        if count > self.max_count {
            return Err(self.err(
                index,
                format!("count {count} is over the limit of {}", self.max_count),
            ));
        }
        Ok(count as usize)
    }

    /// Reads a float accessor of `N` components per element. `types` lists the accepted
    /// accessor types (e.g. VEC3 or VEC4 for colours; missing components are filled with 1).
    /// `force_normalized` treats integer data as normalised whatever the accessor says.
    pub fn read_floats<const N: usize>(
        &self,
        index: usize,
        types: &[Type],
        force_normalized: bool,
    ) -> Result<Vec<[f32; N]>> {
        let acc = self.accessor(index)?;
        let ty = match acc.type_ {
            Checked::Valid(t) if types.contains(&t) => t,
            Checked::Valid(t) => {
                return Err(self.err(index, format!("has type {t:?}, expected one of {types:?}")))
            }
            Checked::Invalid => return Err(self.err(index, "has an invalid type")),
        };
        let comp = match acc.component_type {
            Checked::Valid(c) => c.0,
            Checked::Invalid => return Err(self.err(index, "has an invalid componentType")),
        };
        let normalized = acc.normalized || force_normalized;
        let dim = dimension(ty);
        let count = self.checked_count(index, acc.count.0)?;
        let csize = component_size(comp);
        let elem = dim * csize;
        let mut fill = [0.0f32; N];
        if dim < N {
            fill[dim..].fill(1.0);
        }
        // Check that the data fits before allocating `count` elements: a hostile count with a
        // tiny buffer must be refused without allocating gigabytes.
        let layout = match acc.buffer_view {
            Some(view) => {
                let offset = acc.byte_offset.map_or(0, |o| o.0);
                Some(self.layout(index, view.value(), offset, count as u64, elem, true)?)
            }
            None => None,
        };
        let mut out = vec![fill; count];
        if let Some(l) = layout {
            for (i, v) in out.iter_mut().enumerate() {
                let e = &l.bytes[i * l.stride..i * l.stride + l.elem];
                for (k, slot) in v.iter_mut().enumerate().take(dim.min(N)) {
                    *slot = component(&e[k * csize..], comp, normalized);
                }
            }
        }
        if let Some(sparse) = &acc.sparse {
            let n = self.checked_count(index, sparse.count.0)?;
            if n > count {
                return Err(self.err(
                    index,
                    format!("sparse count {n} exceeds the accessor count {count}"),
                ));
            }
            let ic = match sparse.indices.component_type {
                Checked::Valid(c) => c.0,
                Checked::Invalid => {
                    return Err(self.err(index, "sparse indices have an invalid componentType"))
                }
            };
            let isize_ = component_size(ic);
            let il = self.layout(
                index,
                sparse.indices.buffer_view.value(),
                sparse.indices.byte_offset.0,
                n as u64,
                isize_,
                false,
            )?;
            let vl = self.layout(
                index,
                sparse.values.buffer_view.value(),
                sparse.values.byte_offset.0,
                n as u64,
                elem,
                false,
            )?;
            for s in 0..n {
                let target = index_component(&il.bytes[s * isize_..], ic)
                    .ok_or_else(|| self.err(index, "sparse indices must be unsigned integers"))?
                    as usize;
                let slot = out.get_mut(target).ok_or_else(|| {
                    self.err(
                        index,
                        format!("sparse index {target} is out of range (count {count})"),
                    )
                })?;
                let e = &vl.bytes[s * elem..(s + 1) * elem];
                for (k, c) in slot.iter_mut().enumerate().take(dim.min(N)) {
                    *c = component(&e[k * csize..], comp, normalized);
                }
            }
        }
        Ok(out)
    }

    /// Reads an index accessor (SCALAR of unsigned bytes, shorts or ints).
    pub fn read_indices(&self, index: usize) -> Result<Vec<u32>> {
        let acc = self.accessor(index)?;
        if acc.type_ != Checked::Valid(Type::Scalar) {
            return Err(self.err(index, "indices must be SCALAR"));
        }
        if acc.sparse.is_some() {
            // Sparse index buffers are legal but unheard of; read them through the float path
            // would lose precision, so refuse them clearly.
            return Err(self.err(index, "sparse index accessors are not supported"));
        }
        let comp = match acc.component_type {
            Checked::Valid(c)
                if matches!(
                    c.0,
                    ComponentType::U8 | ComponentType::U16 | ComponentType::U32
                ) =>
            {
                c.0
            }
            _ => return Err(self.err(index, "indices must be unsigned bytes, shorts or ints")),
        };
        let count = self.checked_count(index, acc.count.0)?;
        let Some(view) = acc.buffer_view else {
            return Ok(vec![0; count]);
        };
        let csize = component_size(comp);
        let offset = acc.byte_offset.map_or(0, |o| o.0);
        let l = self.layout(index, view.value(), offset, count as u64, csize, true)?;
        Ok((0..count)
            .map(|i| index_component(&l.bytes[i * l.stride..], comp).unwrap_or(0))
            .collect())
    }

    /// The element count of an accessor.
    pub fn count(&self, index: usize) -> Result<u64> {
        Ok(self.accessor(index)?.count.0)
    }
}
