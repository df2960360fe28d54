#!/usr/bin/env python3
"""Cryptomatte mattes of a Cryptomatte EXR, made by Blender's compositor: a peer to check
lightsplit's Cryptomatte output against (comparison only; Blender is no lightsplit dependency).
Runs in a Python with Blender as the `bpy` module (PyPI's bpy, Blender 5.0) and numpy:

    python cryptomatte_blender.py --exr IN.exr --type CryptoObject --name NAME [--name NAME ...]
        --out OUT_DIR

IN.exr is a single-part scanline EXR after the Cryptomatte specification 1.2: for the type T,
layers T00, T01, ... (channels R G B A: id and coverage of two ranks each) and the header
strings cryptomatte/<key>/name = T, .../hash, .../conversion, .../manifest.

Blender loads IN.exr as a multilayer image, and for each NAME its compositor's Cryptomatte
node (source 'IMAGE', its Cryptomatte type --type as Blender lists it from the file's metadata,
Matte ID NAME) computes the matte: Blender hashes NAME itself (MurmurHash3, as the specification
says) and sums the coverage of every rank, in every layer T00, T01, ..., whose id is that hash.
The matte goes through a Group Output node into the render result (the scene has no Render
Layers node, so no render engine runs, only the compositor), which Blender writes as a 32-bit
float EXR and reads back. The matte is saved as OUT_DIR/NAME.npy, a float32 H x W array whose
row 0 is the image's top row (Blender's pixel rows run bottom-up).

What Blender asks of the file, beyond the specification's letter:
- the manifest embedded in the header: Blender lists a type only when it has both .../name
  and .../manifest (a `manif_file` sidecar is not read); it does not check the key;
- no other layer whose name starts with T (e.g. T = CryptoObject next to CryptoObjectX00):
  Blender would add its ranks to T's (refused here, exit 1);
- the image's colour space is set to Non-Color, or Blender converts every layer, the ids
  too, from the colour space it reads off the header (e.g. `chromaticities`).
Blender's Matte ID is a comma-separated list with spaces trimmed, so a NAME with a comma or
with leading or trailing spaces cannot be asked for (exit 2). A NAME absent from the image
gives an all-zero matte, with a warning on stderr.

Prints one JSON line to stdout: {"mattes": {"NAME": "OUT_DIR/NAME.npy", ...}, "blender":
"5.0.1"}. Exit status: 0 on success; 1 when Blender finds no Cryptomatte type --type in the
EXR, the EXR has no layer T00 or a layer Blender would mistake for one of T's, or the
compositor made no matte; 2 on bad arguments.
"""

import argparse
import contextlib
import json
import os
import struct
import sys
import tempfile

import numpy as np


def fail(message, status=1):
    print(f"cryptomatte_blender: error: {message}", file=sys.stderr)
    sys.exit(status)


@contextlib.contextmanager
def stdout_to_stderr():
    """Blender logs to stdout from C as well as from Python: to stderr at the file-descriptor
    level, so that stdout holds only the JSON line."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def exr_header(path):
    """The first header of an OpenEXR file: {attribute name: (type name, value bytes)}."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
        if data[:4] != b"\x76\x2f\x31\x01":
            fail(f"{path}: not an OpenEXR file")
        attributes, at = {}, 8
        while True:
            try:
                if data[at] == 0:
                    return attributes
                name_end = data.index(b"\0", at)
                type_end = data.index(b"\0", name_end + 1)
                (size,) = struct.unpack_from("<i", data, type_end + 1)
                value_at = type_end + 5
                if value_at + size > len(data):
                    raise IndexError
            except (IndexError, ValueError, struct.error):  # the header goes on past `data`
                more = f.read(len(data))
                if not more:
                    fail(f"{path}: truncated OpenEXR header")
                data += more
                continue
            attributes[data[at:name_end].decode()] = (data[name_end + 1:type_end].decode(),
                                                      data[value_at:value_at + size])
            at = value_at + size


def channel_names(chlist):
    names, at = [], 0
    while chlist[at] != 0:
        end = chlist.index(b"\0", at)
        names.append(chlist[at:end].decode())
        at = end + 17  # pixel type, pLinear and reserved bytes, x and y sampling
    return names


def matte(scene, node, name, out_path):
    """Blender's matte of `name`, float32 H x W, row 0 at the top."""
    node.matte_id = name
    with stdout_to_stderr():
        bpy.ops.render.render(write_still=True)
    if not os.path.isfile(out_path):
        fail(f"the compositor wrote no matte for {name!r}")
    image = bpy.data.images.load(out_path)
    image.colorspace_settings.name = "Non-Color"
    width, height = image.size
    if (width, height) != (scene.render.resolution_x, scene.render.resolution_y):
        fail(f"the compositor's matte for {name!r} is {width} x {height}")
    pixels = np.empty(width * height * image.channels, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    os.remove(out_path)
    return np.ascontiguousarray(pixels.reshape(height, width, -1)[::-1, :, 0])


def main():
    global bpy
    import bpy  # here, so that the header reader above imports without Blender

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--exr", required=True, help="the Cryptomatte EXR")
    p.add_argument("--type", required=True, help="the Cryptomatte type (layer name), e.g. CryptoObject")
    p.add_argument("--name", required=True, action="append", help="a name to make the matte of (repeatable)")
    p.add_argument("--out", required=True, help="directory for NAME.npy")
    a = p.parse_args()
    for name in a.name:
        if not name or "," in name or name != name.strip(" "):
            p.error(f"Blender's Matte ID cannot hold the name {name!r} (a comma, or spaces at an end)")
        if "/" in name or name in (".", ".."):
            p.error(f"the name {name!r} cannot be a file name")
    if not os.path.isfile(a.exr):
        p.error(f"no file {a.exr}")

    header = exr_header(a.exr)
    x_min, y_min, x_max, y_max = struct.unpack("<4i", header["dataWindow"][1])
    layers = {c.rpartition(".")[0] for c in channel_names(header["channels"][1])}
    if f"{a.type}00" not in layers:
        fail(f"{a.exr}: no layer {a.type}00 (channels {a.type}00.R, .G, .B, .A)")
    others = sorted(l for l in layers if l.startswith(a.type) and l != a.type and not l[len(a.type):].isdigit())
    if others:
        fail(f"{a.exr}: Blender would add the layers {', '.join(others)} to the ranks of {a.type} "
             "(it reads every layer whose name starts with the type's)")

    with stdout_to_stderr():
        bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = x_max - x_min + 1
    scene.render.resolution_y = y_max - y_min + 1
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = True
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGBA"

    tree = bpy.data.node_groups.new("Cryptomatte", "CompositorNodeTree")
    scene.compositing_node_group = tree
    node = tree.nodes.new("CompositorNodeCryptomatteV2")
    node.source = "IMAGE"
    image = bpy.data.images.load(os.path.abspath(a.exr))
    # Else Blender converts every layer from the colour space it reads off the header (e.g.
    # ACES2065-1 from a `chromaticities` attribute) to its own, and the ids become noise.
    image.colorspace_settings.name = "Non-Color"
    node.image = image
    try:
        node.layer_name = a.type
    except TypeError as e:  # the message lists the types Blender found
        fail(f"{a.exr}: Blender finds no Cryptomatte type {a.type!r} in its metadata ({e})")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    output = tree.nodes.new("NodeGroupOutput")
    tree.links.new(node.outputs["Matte"], output.inputs[0])

    os.makedirs(a.out, exist_ok=True)
    mattes = {}
    with tempfile.TemporaryDirectory() as tmp:
        scene.render.filepath = os.path.join(tmp, "matte.exr")
        for name in a.name:
            m = matte(scene, node, name, scene.render.filepath)
            if not m.any():
                print(f"cryptomatte_blender: warning: the matte of {name!r} is empty", file=sys.stderr)
            path = os.path.join(a.out, name + ".npy")
            np.save(path, m)
            mattes[name] = path
    print(json.dumps({"mattes": mattes, "blender": bpy.app.version_string}))


if __name__ == "__main__":
    main()
