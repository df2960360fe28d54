//! Issue 34's findings in the scene inputs (glTF, PLY, environment maps, geometry far away): what
//! a hostile user made of the new readers, one test each, each failing before its fix. Every
//! case must be one clear error naming the file, exit status 2, with bounded memory and time:
//! never a panic (101), an abort (134) or a silent wrong image. Memory bombs run under an
//! address-space limit, so that a regression fails fast instead of taking the machine.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::json;

use crate::common::GltfDoc;

/// The address space the bombs run in: a tiny render (Embree's device included) needs about
/// 300 MB of it.
const LIMIT_KIB: u64 = 1 << 20;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs the binary in `dir` with the tiny settings of the findings' recipes, under `ulimit -v`.
fn run(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    run_within(LIMIT_KIB, dir, args, env)
}

/// [`run`] under a limit of `limit` KiB.
fn run_within(limit: u64, dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut all: Vec<&str> = args.to_vec();
    if args.first() == Some(&"render") {
        all.extend(["--spp", "1", "--width", "32", "--height", "32", "--threads", "1"]);
    }
    let mut c = Command::new("sh");
    c.arg("-c").arg(format!("ulimit -v {limit}; exec \"$0\" \"$@\"")).arg(env!("CARGO_BIN_EXE_lightsplit"));
    c.args(&all).current_dir(dir);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("the binary runs")
}

/// Asserts that `file` is refused by `render` (as a model and as a TOML `type = "gltf"` shape,
/// for a glTF) and by `info` with status 2, a message naming it and containing `needle`.
fn refused(dir: &Path, file: &str, needle: &str) {
    let mut commands = vec![vec!["render", file, "-o", "out.exr"], vec!["info", file]];
    let is_gltf = file.ends_with(".gltf") || file.ends_with(".glb");
    if is_gltf {
        let toml = format!(
            "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[shape]]\ntype = \"gltf\"\nfile = \"{file}\"\n"
        );
        std::fs::write(dir.join("with.toml"), toml).expect("write");
        commands.push(vec!["render", "with.toml", "-o", "out.exr"]);
    }
    for args in commands {
        let o = run(dir, &args, &[]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(file) && e.contains(needle), "{args:?}: wanted `{needle}`: {e}");
        assert!(!e.contains("panicked"), "{args:?}: {e}");
        assert!(!dir.join("out.exr").exists(), "{args:?} wrote an image");
    }
}

/// The quad with a node placing it, written as `NAME.gltf` (and `NAME.bin`) after `edit`.
fn gltf(dir: &Path, name: &str, edit: impl FnOnce(&mut GltfDoc)) -> PathBuf {
    let mut doc = GltfDoc::quad();
    doc.node(json!({"mesh": 0}), true);
    edit(&mut doc);
    doc.write_gltf(dir, name)
}

/// A view of its own at the end of the buffer, holding `bytes`.
fn view(doc: &mut GltfDoc, bytes: &[u8], stride: Option<usize>) -> usize {
    while !doc.bin.len().is_multiple_of(4) {
        doc.bin.push(0);
    }
    let mut v = json!({"buffer": 0, "byteOffset": doc.bin.len(), "byteLength": bytes.len()});
    if let Some(s) = stride {
        v["byteStride"] = json!(s);
    }
    doc.bin.extend_from_slice(bytes);
    let views = doc.json["bufferViews"].as_array_mut().expect("views");
    views.push(v);
    views.len() - 1
}

fn accessor(doc: &mut GltfDoc, a: serde_json::Value) -> usize {
    let accessors = doc.json["accessors"].as_array_mut().expect("accessors");
    accessors.push(a);
    accessors.len() - 1
}

/// The control: the unedited quad renders, under the same limit.
#[test]
fn the_quad_itself_renders_under_the_limit() {
    let dir = tempfile::tempdir().expect("tempdir");
    gltf(dir.path(), "q", |_| {});
    let o = run(dir.path(), &["render", "q.gltf", "-o", "q.exr"], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// H1: panics inside the glTF crate (exit 101): a POSITION, NORMAL or TEXCOORD_0 view with a
/// byteStride of 4, below the element; float indices; an image view at offset 10000 of a short
/// buffer; a buffer URI `%FF.bin` with a file `U+FFFD.bin` beside it.
#[test]
fn h1_what_the_crate_panicked_on_is_one_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    for (k, attribute) in ["POSITION", "NORMAL", "TEXCOORD_0"].into_iter().enumerate() {
        let name = format!("stride{k}");
        gltf(d, &name, |doc| {
            let a =
                doc.json["meshes"][0]["primitives"][0]["attributes"][attribute].as_u64().expect("attribute");
            let v = doc.json["accessors"][a as usize]["bufferView"].as_u64().expect("view");
            doc.json["bufferViews"][v as usize]["byteStride"] = json!(4);
        });
        refused(d, &format!("{name}.gltf"), "byteStride of 4");
    }
    gltf(d, "float-indices", |doc| {
        let i = doc.json["meshes"][0]["primitives"][0]["indices"].as_u64().expect("indices");
        doc.json["accessors"][i as usize]["componentType"] = json!(5126);
    });
    refused(d, "float-indices.gltf", "indices are scalars of UNSIGNED_BYTE");
    gltf(d, "image-view", |doc| {
        let png = [0u8; 8];
        let t = doc.texture(&png);
        let image = doc.json["textures"][t]["source"].as_u64().expect("source") as usize;
        let v = doc.json["images"][image]["bufferView"].as_u64().expect("view") as usize;
        doc.json["bufferViews"][v]["byteOffset"] = json!(10000);
        doc.json["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": t}}}]);
        doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    });
    refused(d, "image-view.gltf", "runs past the end of buffer 0");
    let path = gltf(d, "uri", |_| {});
    let text = std::fs::read_to_string(&path).expect("read").replace("uri.bin", "%FF.bin");
    std::fs::write(&path, text).expect("write");
    std::fs::rename(d.join("uri.bin"), d.join("\u{FFFD}.bin")).expect("rename");
    refused(d, "uri.gltf", "%FF.bin");
}

/// H2: a camera node whose matrix turns the camera's up onto its view direction (Y column
/// (0, 0, -1), Z column (0, 0, 1)) made Embree assert and abort (134), and the BVH render only
/// the sky.
#[test]
fn h2_a_camera_whose_up_is_its_view_direction_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    gltf(dir.path(), "camera", |doc| {
        doc.json["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]);
        let m = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 3.0, 1.0];
        doc.node(json!({"camera": 0, "matrix": m}), true);
    });
    let o = run(dir.path(), &["render", "camera.gltf", "-o", "out.exr", "--accel", "embree"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("parallel to the view direction"), "{}", stderr(&o));
}

/// H3 and L6: an accessor without a buffer view whose sparse values declare a count of 1e12
/// (or 3e7: 1.5 GB), as positions and as indices, allocated without bound; a count of
/// 2^62 + 1 said "index 1 out of range (1 vertices)".
#[test]
fn h3_counts_no_bytes_back_are_refused_before_allocating() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    for (k, count) in [1e12 as u64, 3e7 as u64].into_iter().enumerate() {
        for (target, kind, component) in [("POSITION", "VEC3", 5126), ("indices", "SCALAR", 5125)] {
            let name = format!("sparse{k}{target}");
            gltf(d, &name, |doc| {
                let indices = view(doc, &0u32.to_le_bytes(), None);
                let values = view(doc, &[0u8; 12], None);
                let a = accessor(
                    doc,
                    json!({"componentType": component, "count": count, "type": kind, "min": [0, 0, 0], "max": [0, 0, 0], "sparse": {
                    "count": 1, "indices": {"bufferView": indices, "componentType": 5125},
                    "values": {"bufferView": values}}}),
                );
                let primitive = &mut doc.json["meshes"][0]["primitives"][0];
                match target {
                    "indices" => primitive["indices"] = json!(a),
                    _ => primitive["attributes"]["POSITION"] = json!(a),
                }
            });
            let file = format!("{name}.gltf");
            let needle = if count > 1 << 28 { "over the 268435456 read at most" } else { "no buffer view" };
            refused(d, &file, needle);
        }
    }
    gltf(d, "huge", |doc| doc.json["accessors"][0]["count"] = json!((1u64 << 62) + 1));
    refused(d, "huge.gltf", "a count of 4611686018427387905");
}

/// H6: a 257-byte PLY with `element junk 100000000` and no properties, or a vertex element with
/// none, exhausted memory; so did face lists the file cannot hold; 15 MB of empty face lists
/// were amplified 200 times.
#[test]
fn h6_ply_counts_are_held_to_the_bytes_that_follow() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let header = "ply\nformat binary_little_endian 1.0\n";
    let vertices = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    let faces = "element face 1\nproperty list uchar int vertex_indices\n";
    let mut triangle = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        v.iter().for_each(|x| triangle.extend(x.to_le_bytes()));
    }
    triangle.push(3);
    [0i32, 1, 2].iter().for_each(|i| triangle.extend(i.to_le_bytes()));
    let mut empty = format!("{header}element vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 5000000\nproperty list uchar int vertex_indices\nend_header\n").into_bytes();
    empty.extend_from_slice(&triangle[..36]);
    empty.extend(std::iter::repeat_n(0u8, 5_000_000));
    for (name, bytes, needle) in [
        ("junk", [format!("{header}element junk 100000000\n{vertices}{faces}end_header\n").into_bytes(), triangle.clone()].concat(), "element `junk` has no properties"),
        ("bare", format!("{header}element vertex 100000000\n{faces}end_header\n").into_bytes(), "element `vertex` has no properties"),
        ("many", [format!("{header}element vertex 300000000\nproperty float x\nproperty float y\nproperty float z\n{faces}end_header\n").into_bytes(), triangle.clone()].concat(), "declares 300000000 elements"),
        ("empty", empty, "face 0 has 0 vertices"),
    ] {
        let file = format!("{name}.ply");
        std::fs::write(d.join(&file), bytes).expect("write");
        let toml = format!("[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[shape]]\ntype = \"mesh\"\nfile = \"{file}\"\n");
        std::fs::write(d.join(format!("{name}.toml")), toml).expect("write");
        for args in [["render", &format!("{name}.toml"), "-o", "out.exr"].as_slice(), &["info", &format!("{name}.toml")]] {
            let o = run(d, args, &[]);
            assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
            assert!(stderr(&o).contains(&file) && stderr(&o).contains(needle), "{name}: {}", stderr(&o));
        }
    }
    // The control: the same triangle with a count the bytes hold renders.
    std::fs::write(
        d.join("ok.ply"),
        [format!("{header}{vertices}{faces}end_header\n").into_bytes(), triangle].concat(),
    )
    .expect("write");
    std::fs::write(d.join("ok.toml"), "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[shape]]\ntype = \"mesh\"\nfile = \"ok.ply\"\n").expect("write");
    let o = run(d, &["render", "ok.toml", "-o", "ok.exr"], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// M1 (the glTF part): an emissive factor of 1e20 exited 0 with infinities in the variance
/// layers; a glTF surface is held to the scene file's emission bound.
#[test]
fn m1_gltf_emission_is_bounded_as_a_scene_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    gltf(dir.path(), "bright", |doc| {
        doc.json["materials"] = json!([{"emissiveFactor": [1e20, 1e20, 1e20]}]);
        doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    });
    refused(dir.path(), "bright.gltf", "over the 1e12 a surface may emit");
}

/// M2: a node that is its own child took 11 s and 3 GB before its error; nodes shared by two
/// parents on each of 40 levels (2^40 placements) took 2 GB and then said "a node is its own
/// ancestor". Both fail at once, naming the node.
#[test]
fn m2_node_cycles_and_shared_nodes_fail_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    gltf(dir.path(), "cycle", |doc| {
        doc.json["nodes"][0]["children"] = json!([0]);
    });
    refused(dir.path(), "cycle.gltf", "node 0 is its own child");
    gltf(dir.path(), "dag", |doc| {
        for level in 0..40 {
            let next = 1 + 2 * (level + 1);
            let children = if level == 39 { json!([]) } else { json!([next, next + 1]) };
            doc.node(json!({"mesh": 0, "children": children.clone()}), level == 0);
            doc.node(json!({"mesh": 0, "children": children}), false);
        }
    });
    refused(dir.path(), "dag.gltf", "is a child of both node");
}

/// M3: twenty large PNGs of which one is used were all decoded at once (3.2 GB for twenty of
/// 6000^2). Only what a material uses is decoded, one at a time: here ninety textures of a
/// 3000^2 PNG in 400 MB (before, the decoding of all of them aborted in it).
#[test]
fn m3_only_the_images_a_material_uses_are_decoded() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut png = Vec::new();
    image::RgbImage::from_pixel(3000, 3000, image::Rgb([200, 100, 50]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    gltf(dir.path(), "images", |doc| {
        let textures: Vec<usize> = (0..90).map(|_| doc.texture(&png)).collect();
        doc.json["materials"] =
            json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": textures[7]}}}]);
        doc.json["meshes"][0]["primitives"][0]["material"] = json!(0);
    });
    let o =
        run_within(400 << 10, dir.path(), &["render", "images.gltf", "-o", "out.exr", "--accel", "bvh"], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// M4: `../../../../../../etc/passwd` and `/etc/passwd` as buffer URIs were read; a
/// `file:///dev/zero` URI beside a decoy regular file named `file:/dev/zero` passed the input
/// check and then read /dev/zero. Each is refused; LIGHTSPLIT_ALLOW_OUTSIDE_FILES=1 lets a file
/// outside the directory be read.
#[test]
fn m4_uris_stay_in_the_gltf_directory() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path().join("model");
    std::fs::create_dir_all(d.join("file:/dev")).expect("mkdir");
    let path = gltf(&d, "m", |_| {});
    std::fs::copy(d.join("m.bin"), d.join("file:/dev/zero")).expect("decoy");
    std::fs::rename(d.join("m.bin"), dir.path().join("outside.bin")).expect("move");
    let text = std::fs::read_to_string(&path).expect("read");
    for (uri, needle) in [
        ("../../../../../../etc/passwd", "a path outside the glTF's directory"),
        ("/etc/passwd", "a path outside the glTF's directory"),
        ("file:///dev/zero", "a URI with a scheme is not read"),
        ("file:/dev/zero", "a URI with a scheme is not read"),
        ("../outside.bin", "a path outside the glTF's directory"),
    ] {
        std::fs::write(&path, text.replace("m.bin", uri)).expect("write");
        refused(&d, "m.gltf", needle);
    }
    let o = run(&d, &["render", "m.gltf", "-o", "out.exr"], &[("LIGHTSPLIT_ALLOW_OUTSIDE_FILES", "1")]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // A link inside the directory to a file outside it is outside too.
    std::os::unix::fs::symlink(dir.path().join("outside.bin"), d.join("link.bin")).expect("symlink");
    std::fs::write(&path, text.replace("m.bin", "link.bin")).expect("write");
    std::fs::remove_file(d.join("out.exr")).expect("remove");
    refused(&d, "m.gltf", "leads outside the glTF's directory");
}

/// L1 and L2: a vertex at 3e38 wrote an infinite depth through the BVH while Embree dropped its
/// triangle; a glTF placed at a scale of 1e20 vanished silently on both backends.
#[test]
fn l1_l2_geometry_beyond_f32_rays_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let obj = "v 0 0 0\nv 1 0 0\nv 0 3e38 0\nf 1 2 3\n";
    std::fs::write(d.join("far.obj"), obj).expect("write");
    std::fs::write(d.join("far.toml"), "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[shape]]\ntype = \"mesh\"\nfile = \"far.obj\"\n").expect("write");
    gltf(d, "q", |_| {});
    std::fs::write(d.join("huge.toml"), "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[shape]]\ntype = \"gltf\"\nfile = \"q.gltf\"\ntransform = { scale = 1e20 }\n").expect("write");
    for scene in ["far.toml", "huge.toml"] {
        for accel in ["embree", "bvh"] {
            let o = run(d, &["render", scene, "-o", "out.exr", "--accel", accel], &[]);
            assert_eq!(o.status.code(), Some(2), "{scene}: {}", stderr(&o));
            assert!(stderr(&o).contains("that rays in f32 can trace"), "{scene}: {}", stderr(&o));
        }
    }
}

/// L3: an `.hdr` whose every RGBE pixel is `ff ff ff ff` (1.7e38) overflowed its sampling's
/// sums and was dropped as black: an all-zero image with exit 0.
#[test]
fn l3_an_environment_that_overflows_its_sums_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8 +X 16\n".to_vec();
    hdr.extend(std::iter::repeat_n(0xffu8, 8 * 16 * 4));
    std::fs::write(dir.path().join("white.hdr"), hdr).expect("write");
    let toml = "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n[[light]]\ntype = \"environment\"\nfile = \"white.hdr\"\n\
                [[shape]]\ntype = \"sphere\"\nradius = 1\n";
    std::fs::write(dir.path().join("env.toml"), toml).expect("write");
    let o = run(dir.path(), &["render", "env.toml", "-o", "out.exr"], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("white.hdr") && stderr(&o).contains("scale it down"), "{}", stderr(&o));
}

/// L7: silently accepted glTF: a directional light whose node has a zero scale (no direction:
/// a black image); UNSIGNED_BYTE positions read as floats; an index count of 2, which draws
/// nothing.
#[test]
fn l7_gltf_that_drew_nothing_or_garbage_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    gltf(d, "sun", |doc| {
        doc.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
        doc.json["extensions"] =
            json!({"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 3.0}]}});
        doc.node(json!({"scale": [0, 0, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}}), true);
    });
    refused(d, "sun.gltf", "no direction");
    gltf(d, "bytes", |doc| {
        let v = view(doc, &[0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0, 0], Some(4));
        let a = accessor(
            doc,
            json!({"bufferView": v, "componentType": 5121, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}),
        );
        doc.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(a);
    });
    refused(d, "bytes.gltf", "does not use KHR_mesh_quantization, which allows integers here");
    gltf(d, "two", |doc| {
        let a = doc.indices(&[0, 1]);
        doc.json["meshes"][0]["primitives"][0]["indices"] = json!(a);
    });
    refused(d, "two.gltf", "2 indices (or vertices) do not make whole triangles");
}

mod fuzz {
    //! The third line of defence: the glTF and PLY readers take thousands of mutated files
    //! (bytes flipped, inserted, cut; JSON numbers changed) and never panic. Fixed seeds, so a
    //! CI run takes seconds and finds the same cases every time.

    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

    use crate::common::GltfDoc;

    /// A mutation of `base`: each op flips, inserts or removes a byte at a position, or cuts
    /// the file.
    fn mutate(base: &[u8], ops: &[(u8, u32, u8)]) -> Vec<u8> {
        let mut b = base.to_vec();
        for &(op, at, byte) in ops {
            if b.is_empty() {
                break;
            }
            let i = at as usize % b.len();
            match op % 4 {
                0 => b[i] ^= byte | 1,
                1 => b.insert(i, byte),
                2 => {
                    b.remove(i);
                }
                _ => b.truncate(i),
            }
        }
        b
    }

    /// The digits of the JSON chunk of a GLB changed one at a time: counts, offsets, strides
    /// and indices that lie.
    fn mutate_numbers(base: &[u8], ops: &[(u32, u8)]) -> Vec<u8> {
        let mut b = base.to_vec();
        let digits: Vec<usize> = (20..b.len().min(2000)).filter(|&i| b[i].is_ascii_digit()).collect();
        for &(at, d) in ops {
            if let Some(&i) = digits.get(at as usize % digits.len().max(1)) {
                b[i] = b'0' + d % 10;
            }
        }
        b
    }

    fn runner(seed: u8) -> TestRunner {
        let config = Config { cases: 400, failure_persistence: None, ..Config::default() };
        TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[seed; 32]))
    }

    fn ply() -> Vec<u8> {
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty float u\nproperty float v\nelement face 2\nproperty list uchar int vertex_indices\n\
element junk 1\nproperty list ushort double values\nend_header\n"
            .to_vec();
        for v in [
            [0.0f32, 0.0, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0, 1.0, 1.0],
            [0.0, 1.0, 0.0, 0.0, 1.0],
        ] {
            v.iter().for_each(|x| b.extend(x.to_le_bytes()));
        }
        for f in [[0i32, 1, 2], [0, 2, 3]] {
            b.push(3);
            f.iter().for_each(|i| b.extend(i.to_le_bytes()));
        }
        b.extend(2u16.to_le_bytes());
        b.extend(1.0f64.to_le_bytes());
        b.extend(2.0f64.to_le_bytes());
        b
    }

    #[test]
    fn mutated_gltf_and_ply_never_panic() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut doc = GltfDoc::quad();
        doc.node(serde_json::json!({"mesh": 0}), true);
        let mut png = Vec::new();
        image::RgbImage::from_pixel(4, 4, image::Rgb([9, 99, 199]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("png");
        let t = doc.texture(&png);
        doc.json["materials"] =
            serde_json::json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": t}}}]);
        doc.json["meshes"][0]["primitives"][0]["material"] = serde_json::json!(0);
        let glb = doc.glb();
        let ply = ply();
        assert!(
            lightsplit::scene::ply::load(&write(dir.path(), "base.ply", &ply)).is_ok_and(|p| p.len() == 1)
        );
        assert!(lightsplit::scene::gltf::load(&write(dir.path(), "base.glb", &glb)).is_ok());
        let ops = proptest::collection::vec((any::<u8>(), any::<u32>(), any::<u8>()), 1..6);
        runner(1)
            .run(&ops, |ops| {
                let path = write(dir.path(), "m.glb", &mutate(&glb, &ops));
                let _ = lightsplit::scene::gltf::load(&path);
                let path = write(dir.path(), "m.ply", &mutate(&ply, &ops));
                let _ = lightsplit::scene::ply::load(&path);
                Ok(())
            })
            .expect("no panic");
        let numbers = proptest::collection::vec((any::<u32>(), any::<u8>()), 1..4);
        runner(2)
            .run(&numbers, |ops| {
                let path = write(dir.path(), "n.glb", &mutate_numbers(&glb, &ops));
                let _ = lightsplit::scene::gltf::load(&path);
                let path = write(dir.path(), "n.ply", &mutate_numbers(&ply, &ops));
                let _ = lightsplit::scene::ply::load(&path);
                Ok(())
            })
            .expect("no panic");
    }

    fn write(dir: &std::path::Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, bytes).expect("write");
        path
    }
}
