//! Helpers shared by the integration tests (each test binary uses some of them).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use lightsplit::render::{render, RenderOptions, RenderOutput};
use lightsplit::scene::file::parse;

/// Runs the `lightsplit` binary with `args`.
pub fn lightsplit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightsplit")).args(args).output().expect("the binary runs")
}

/// Renders a scene given as text at `spp`, with the file's other settings.
pub fn render_text(text: &str, spp: u32) -> RenderOutput {
    let scene = parse(Path::new("test.toml"), text).expect("scene parses");
    let mut options = RenderOptions::from_scene(&scene);
    options.spp = spp;
    render(&scene, &options, &|_| {}).expect("renders")
}

/// The mean of the red channel and its standard error from the spread of the pixels (each pixel
/// an independent estimate of the same value).
pub fn mean_and_standard_error(image: &lightsplit::film::Image) -> (f64, f64) {
    let values: Vec<f64> = image.pixels.iter().map(|p| p.x as f64).collect();
    mean_and_standard_error_of(&values)
}

/// The mean of `values` (independent estimates of the same value) and its standard error.
pub fn mean_and_standard_error_of(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The six faces of the cube [-1, 1]^3 as scene-file quads, wound so that their front (emitting)
/// side faces inwards; `keys` (TOML lines such as `material = "white"`) go into each.
pub fn inward_cube(keys: &str) -> String {
    let mut text = String::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let corner = |a: f32, b: f32| {
                let mut p = [0.0f32; 3];
                p[axis] = sign;
                p[(axis + 1) % 3] = a;
                p[(axis + 2) % 3] = b;
                format!("[{}, {}, {}]", p[0], p[1], p[2])
            };
            // (a, b) counter-clockwise gives a normal along +axis; reverse it on the + side.
            let mut quad = [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)];
            if sign > 0.0 {
                quad.reverse();
            }
            text.push_str(&format!("[[shape]]\ntype = \"quad\"\n{keys}\nvertices = [{}]\n", quad.join(", ")));
        }
    }
    text
}

/// A portable float map (RGB, little-endian) of `values`, three a pixel, in the file's order:
/// the bottom row first.
pub fn pfm(width: u32, height: u32, values: &[f32]) -> Vec<u8> {
    let mut bytes = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    values.iter().for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    bytes
}

/// A glTF document being built for a test: JSON and its binary buffer.
pub struct GltfDoc {
    pub json: serde_json::Value,
    pub bin: Vec<u8>,
}

impl GltfDoc {
    /// A document with one mesh: a unit quad in the xy plane facing +z (two triangles, with
    /// normals and texture coordinates), no nodes yet.
    pub fn quad() -> GltfDoc {
        let mut doc = GltfDoc {
            json: serde_json::json!({
                "asset": {"version": "2.0"},
                "scene": 0,
                "scenes": [{"nodes": []}],
                "nodes": [],
                "bufferViews": [],
                "accessors": [],
            }),
            bin: Vec::new(),
        };
        let p = doc.floats(&[-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0], "VEC3");
        let n = doc.floats(&[0.0, 0.0, 1.0].repeat(4), "VEC3");
        let t = doc.floats(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0], "VEC2");
        let i = doc.indices(&[0, 1, 2, 0, 2, 3]);
        doc.json["meshes"] = serde_json::json!([{"name": "quad", "primitives": [{
            "attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t}, "indices": i
        }]}]);
        doc
    }

    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let views = self.json["bufferViews"].as_array_mut().expect("views");
        views.push(serde_json::json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        views.len() - 1
    }

    /// An accessor of floats, `kind` VEC2, VEC3 or VEC4 (min and max given for VEC3, as
    /// positions need).
    pub fn floats(&mut self, v: &[f32], kind: &str) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let values: Vec<f64> = v.iter().map(|&x| x as f64).collect();
        self.vectors(&bytes, &values, kind, serde_json::json!({"componentType": 5126}))
    }

    /// An accessor of signed shorts (KHR_mesh_quantization's integers), `kind` VEC2, VEC3 or
    /// VEC4, normalized or not (min and max given for VEC3, as positions need).
    pub fn shorts(&mut self, v: &[i16], kind: &str, normalized: bool) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let values: Vec<f64> = v.iter().map(|&x| x as f64).collect();
        self.vectors(
            &bytes,
            &values,
            kind,
            serde_json::json!({"componentType": 5122, "normalized": normalized}),
        )
    }

    /// An accessor of `bytes` holding `values` as vectors of `kind`, with the keys of `a`.
    fn vectors(&mut self, bytes: &[u8], values: &[f64], kind: &str, mut a: serde_json::Value) -> usize {
        let view = self.view(bytes);
        let width = match kind {
            "VEC2" => 2,
            "VEC4" => 4,
            _ => 3,
        };
        (a["bufferView"], a["count"], a["type"]) = (view.into(), (values.len() / width).into(), kind.into());
        if kind == "VEC3" {
            let at = |k: usize| values.iter().skip(k).step_by(3).copied();
            a["min"] =
                serde_json::json!((0..3).map(|k| at(k).fold(f64::INFINITY, f64::min)).collect::<Vec<_>>());
            a["max"] = serde_json::json!((0..3)
                .map(|k| at(k).fold(f64::NEG_INFINITY, f64::max))
                .collect::<Vec<_>>());
        }
        let accessors = self.json["accessors"].as_array_mut().expect("accessors");
        accessors.push(a);
        accessors.len() - 1
    }

    /// An accessor of u32 indices.
    pub fn indices(&mut self, v: &[u32]) -> usize {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let accessors = self.json["accessors"].as_array_mut().expect("accessors");
        accessors.push(serde_json::json!({"bufferView": view, "componentType": 5125, "count": v.len(), "type": "SCALAR"}));
        accessors.len() - 1
    }

    /// Adds an image (PNG bytes) in the buffer and a texture of it; returns the texture's index.
    pub fn texture(&mut self, png: &[u8]) -> usize {
        let view = self.view(png);
        let images =
            self.json.as_object_mut().expect("object").entry("images").or_insert(serde_json::json!([]));
        let images = images.as_array_mut().expect("images");
        images.push(serde_json::json!({"bufferView": view, "mimeType": "image/png"}));
        let image = images.len() - 1;
        let textures =
            self.json.as_object_mut().expect("object").entry("textures").or_insert(serde_json::json!([]));
        let textures = textures.as_array_mut().expect("textures");
        textures.push(serde_json::json!({"source": image}));
        textures.len() - 1
    }

    /// Adds a node (a JSON object); a root node is listed in the scene. Returns its index.
    pub fn node(&mut self, node: serde_json::Value, root: bool) -> usize {
        let nodes = self.json["nodes"].as_array_mut().expect("nodes");
        nodes.push(node);
        let i = nodes.len() - 1;
        if root {
            self.json["scenes"][0]["nodes"].as_array_mut().expect("scene").push(serde_json::json!(i));
        }
        i
    }

    /// Writes `NAME.gltf` with its buffer in `NAME.bin` beside it; returns the glTF's path.
    pub fn write_gltf(&self, dir: &Path, name: &str) -> std::path::PathBuf {
        let mut json = self.json.clone();
        json["buffers"] = serde_json::json!([{"uri": format!("{name}.bin"), "byteLength": self.bin.len()}]);
        std::fs::write(dir.join(format!("{name}.bin")), &self.bin).expect("write");
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, serde_json::to_vec_pretty(&json).expect("json")).expect("write");
        path
    }

    /// The document as one binary glTF (`.glb`) file's bytes.
    pub fn glb(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        json["buffers"] = serde_json::json!([{"byteLength": self.bin.len()}]);
        let mut j = serde_json::to_vec(&json).expect("json");
        while !j.len().is_multiple_of(4) {
            j.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + j.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(j.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&j);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// A xorshift64 stream of numbers in [0, 1) from `seed` (not 0): cheap, reproducible
/// randomness for ray and point sets.
pub fn uniform_stream(seed: u64) -> impl FnMut() -> f32 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    }
}
