//! Helpers shared by the scene-loading integration tests: temporary folders, loads bounded in
//! time (a hang or a panic fails the test), assertions on errors and warnings, and a tiny glTF
//! builder that makes a valid document (JSON + binary buffer) for each test to break one thing.

#![allow(dead_code)] // Each test file uses its own subset.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use pathlight_scene::{Environment, Limits, Scene, SceneError};
use serde_json::{json, Value};

/// How long one load may take before the test calls it a hang.
pub const TIME_LIMIT: Duration = Duration::from_secs(10);

// ---------------------------------------------------------------------------------------------
// Temporary folders

/// A fresh folder under the system's temporary folder, removed on drop.
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        // The tag is not part of the name: keywords looked for in messages must come from the
        // message, not from the folder's name.
        let _ = tag;
        let path = std::env::temp_dir().join(format!("pathlight-test-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).expect("create a temporary folder");
        Self(path)
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// A subfolder (created).
    pub fn sub(&self, name: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::create_dir_all(&p).expect("create a subfolder");
        p
    }

    /// Writes `bytes` to `name` inside the folder and returns its path.
    pub fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        write(&self.0, name, bytes)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write a test file");
    p
}

// ---------------------------------------------------------------------------------------------
// Loads bounded in time

/// Runs `f` on its own thread and returns its result. A panic in `f` fails the test (with the
/// panic's message); so does taking longer than [`TIME_LIMIT`] (the thread is left behind).
pub fn timed<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    let start = Instant::now();
    let handle = std::thread::Builder::new()
        .name(format!("load {what}"))
        .spawn(move || {
            let _ = tx.send(f());
        })
        .expect("spawn the loading thread");
    match rx.recv_timeout(TIME_LIMIT) {
        Ok(v) => {
            let _ = handle.join();
            v
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => {
            let message = match handle.join() {
                Err(p) => p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default(),
                Ok(()) => String::new(),
            };
            panic!("loading {what} panicked: {message}")
        }
        Err(mpsc::RecvTimeoutError::Timeout) => {
            panic!("loading {what} hung: no answer after {:?}", start.elapsed())
        }
    }
}

/// `pathlight_scene::load_file` with a time bound.
pub fn load(path: &Path, limits: Limits) -> Result<Scene, SceneError> {
    let p = path.to_path_buf();
    timed(&path.display().to_string(), move || {
        pathlight_scene::load_file(&p, &limits)
    })
}

/// `Environment::load` with a time bound.
pub fn load_env(path: &Path, intensity: f32, limits: Limits) -> Result<Environment, SceneError> {
    let p = path.to_path_buf();
    timed(&path.display().to_string(), move || {
        Environment::load(&p, 0.0, intensity, &limits)
    })
}

fn contains_ci(haystack: &str, needle: &str) -> bool {
    haystack.to_lowercase().contains(&needle.to_lowercase())
}

/// Asserts that `result` is an error whose message names `file_name` and contains every keyword
/// (case-insensitive). Returns the message.
#[track_caller]
pub fn assert_err<T>(result: Result<T, SceneError>, file_name: &str, keywords: &[&str]) -> String {
    let err = match result {
        Ok(_) => panic!("expected an error naming {file_name} with {keywords:?}, but it loaded"),
        Err(e) => e,
    };
    let message = err.to_string();
    assert!(
        message.contains(file_name),
        "the error does not name {file_name}: {message}"
    );
    for k in keywords {
        assert!(
            contains_ci(&message, k),
            "the error lacks \"{k}\": {message}"
        );
    }
    message
}

/// Loads `path` and asserts an error naming the file (or `file_name` when given) with keywords.
#[track_caller]
pub fn expect_err(path: &Path, limits: Limits, keywords: &[&str]) -> String {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    assert_err(load(path, limits), &name, keywords)
}

/// Loads `path`, which must load.
#[track_caller]
pub fn expect_ok(path: &Path, limits: Limits) -> Scene {
    match load(path, limits) {
        Ok(s) => s,
        Err(e) => panic!("expected {} to load, got: {e}", path.display()),
    }
}

/// Returns the one warning of `scene` holding every keyword (case-insensitive), or fails.
#[track_caller]
pub fn warning<'a>(scene: &'a Scene, keywords: &[&str]) -> &'a str {
    scene
        .warnings
        .iter()
        .find(|w| keywords.iter().all(|k| contains_ci(w, k)))
        .unwrap_or_else(|| panic!("no warning with {keywords:?} in {:#?}", scene.warnings))
}

/// Limits with small values for tests of the limits themselves.
pub fn limits() -> Limits {
    Limits::default()
}

// ---------------------------------------------------------------------------------------------
// Images

/// A PNG of `w` x `h` pixels from a function of (x, y).
pub fn png(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> Vec<u8> {
    let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y)));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("encode a PNG");
    out
}

/// CRC-32 (IEEE) as PNG chunks use it, bit by bit (no table: only a few bytes are hashed).
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

/// A PNG whose (valid, CRC-checked) header claims `w` x `h` RGBA pixels, followed by a tiny
/// IDAT that holds nowhere near that many.
pub fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]); // 8 bits, RGBA, deflate, adaptive, no interlace
    png_chunk(&mut out, b"IHDR", &ihdr);
    // A zlib stream of one empty stored block.
    png_chunk(
        &mut out,
        b"IDAT",
        &[0x78, 0x01, 0x01, 0x00, 0x00, 0xff, 0xff, 0, 0, 0, 1],
    );
    png_chunk(&mut out, b"IEND", &[]);
    out
}

// ---------------------------------------------------------------------------------------------
// glTF documents

pub const FLOAT: u32 = 5126;
pub const UNSIGNED_INT: u32 = 5125;
pub const UNSIGNED_SHORT: u32 = 5123;

/// A glTF document under construction: the JSON and the bytes of buffer 0.
///
/// Made valid by the constructors (one scene, one node, one mesh, one primitive); tests then
/// change one thing with [`set`](Self::set) or by editing `json` directly.
#[derive(Debug, Clone)]
pub struct Doc {
    pub json: Value,
    pub bin: Vec<u8>,
}

impl Doc {
    /// One node with mesh 0, whose primitive 0 has no attributes yet.
    pub fn empty() -> Self {
        Self {
            json: json!({
                "asset": {"version": "2.0", "generator": "pathlight tests"},
                "scene": 0,
                "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0}],
                "meshes": [{"primitives": [{"attributes": {}}]}],
                "buffers": [{"byteLength": 0}],
                "bufferViews": [],
                "accessors": [],
            }),
            bin: Vec::new(),
        }
    }

    /// A mesh of `positions`, indexed (u32) when `indices` is given.
    pub fn mesh(positions: &[[f32; 3]], indices: Option<&[u32]>) -> Self {
        let mut d = Self::empty();
        let pos = d.add_positions(positions);
        d.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(pos);
        if let Some(idx) = indices {
            let i = d.add_indices(idx);
            d.json["meshes"][0]["primitives"][0]["indices"] = json!(i);
        }
        d
    }

    /// One triangle: accessor 0 is POSITION (3 VEC3), accessor 1 the indices (3 u32).
    pub fn triangle() -> Self {
        Self::mesh(
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            Some(&[0, 1, 2]),
        )
    }

    /// A unit square of two triangles: accessor 0 POSITION (4), accessor 1 indices (6).
    pub fn quad() -> Self {
        Self::mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            Some(&[0, 1, 2, 0, 2, 3]),
        )
    }

    /// The primitive 0 of mesh 0.
    pub fn prim(&mut self) -> &mut Value {
        &mut self.json["meshes"][0]["primitives"][0]
    }

    /// Appends `bytes` (4-byte aligned) to buffer 0 as a new bufferView; returns its index.
    pub fn add_view(&mut self, bytes: &[u8]) -> usize {
        while self.bin.len() & 3 != 0 {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.json["buffers"][0]["byteLength"] = json!(self.bin.len());
        push(
            &mut self.json["bufferViews"],
            json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}),
        )
    }

    /// Adds an accessor; returns its index.
    pub fn add_accessor(&mut self, view: usize, component: u32, count: usize, ty: &str) -> usize {
        push(
            &mut self.json["accessors"],
            json!({"bufferView": view, "componentType": component, "count": count, "type": ty}),
        )
    }

    /// A VEC3 float accessor with min and max (as POSITION requires), over the finite values.
    pub fn add_positions(&mut self, p: &[[f32; 3]]) -> usize {
        let a = self.add_floats(p.iter().flatten().copied(), p.len(), "VEC3");
        let finite = p.iter().filter(|v| v.iter().all(|c| c.is_finite()));
        let mut min = [0.0f32; 3];
        let mut max = [0.0f32; 3];
        for (i, v) in finite.enumerate() {
            for k in 0..3 {
                min[k] = if i == 0 { v[k] } else { min[k].min(v[k]) };
                max[k] = if i == 0 { v[k] } else { max[k].max(v[k]) };
            }
        }
        self.json["accessors"][a]["min"] = json!(min);
        self.json["accessors"][a]["max"] = json!(max);
        a
    }

    /// A float accessor of `count` elements of type `ty` from `values`.
    pub fn add_floats(
        &mut self,
        values: impl IntoIterator<Item = f32>,
        count: usize,
        ty: &str,
    ) -> usize {
        let bytes: Vec<u8> = values.into_iter().flat_map(f32::to_le_bytes).collect();
        let v = self.add_view(&bytes);
        self.add_accessor(v, FLOAT, count, ty)
    }

    /// A SCALAR u32 index accessor.
    pub fn add_indices(&mut self, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = idx.iter().flat_map(|i| i.to_le_bytes()).collect();
        let v = self.add_view(&bytes);
        self.add_accessor(v, UNSIGNED_INT, idx.len(), "SCALAR")
    }

    /// Sets the value at a JSON pointer ("/accessors/0/count"), creating the last key of an
    /// object, or appending when the last key is an array's length.
    pub fn set(&mut self, pointer: &str, value: Value) -> &mut Self {
        let (parent, key) = pointer.rsplit_once('/').expect("a JSON pointer");
        let slot = self
            .json
            .pointer_mut(parent)
            .unwrap_or_else(|| panic!("no {parent} in the document"));
        match slot {
            Value::Object(map) => {
                map.insert(key.to_string(), value);
            }
            Value::Array(items) => {
                let i: usize = key.parse().expect("an array index");
                if i == items.len() {
                    items.push(value);
                } else {
                    items[i] = value;
                }
            }
            other => panic!("{parent} is {other}, not an object or array"),
        }
        self
    }

    /// Removes the value at a JSON pointer (an object key).
    pub fn remove(&mut self, pointer: &str) -> &mut Self {
        let (parent, key) = pointer.rsplit_once('/').expect("a JSON pointer");
        if let Some(Value::Object(map)) = self.json.pointer_mut(parent) {
            map.remove(key);
        }
        self
    }

    /// Gives primitive 0 material 0 with a base colour texture from image `image` (JSON).
    pub fn textured(&mut self, image: Value) -> &mut Self {
        self.json["images"] = json!([image]);
        self.json["textures"] = json!([{"source": 0}]);
        self.json["materials"] = json!([{
            "name": "textured",
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}
        }]);
        self.prim()["material"] = json!(0);
        self
    }

    pub fn json_bytes(&self) -> Vec<u8> {
        serde_json::to_vec_pretty(&self.json).expect("serialise JSON")
    }

    /// The document as GLB: buffer 0 (without a URI) is the BIN chunk.
    pub fn glb(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        if let Some(b) = json["buffers"].get_mut(0).and_then(Value::as_object_mut) {
            b.remove("uri");
        }
        let text = serde_json::to_vec(&json).expect("serialise JSON");
        pathlight_scene::gltf::glb::write(&text, Some(&self.bin))
    }

    /// Writes `name.gltf` into `dir`. Unless buffer 0 already has a URI, the buffer is written
    /// to `name.bin` beside it.
    pub fn write_gltf(&self, dir: &Path, name: &str) -> PathBuf {
        let mut doc = self.clone();
        if doc.json["buffers"][0].get("uri").is_none() && !doc.bin.is_empty() {
            let bin = format!("{name}.bin");
            write(dir, &bin, &doc.bin);
            doc.json["buffers"][0]["uri"] = json!(bin);
        }
        write(dir, &format!("{name}.gltf"), doc.json_bytes())
    }

    /// Writes `name.glb` into `dir`.
    pub fn write_glb(&self, dir: &Path, name: &str) -> PathBuf {
        write(dir, &format!("{name}.glb"), self.glb())
    }
}

fn push(array: &mut Value, item: Value) -> usize {
    if !array.is_array() {
        *array = json!([]);
    }
    let a = array.as_array_mut().expect("an array");
    a.push(item);
    a.len() - 1
}
