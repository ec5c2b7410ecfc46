#!/usr/bin/env python3
"""Mitsuba 3 peer for arbor's `builtin:cornell`: the same scene, rendered by Mitsuba's
`path` integrator, as the reference and the measuring stick for arbor's path tracer.

    mitsuba_cornell.py --spp 64 --out img.exr          one render
    mitsuba_cornell.py --reference --out ref.exr       a converged render (8192 spp)
    mitsuba_cornell.py --ladder --reference ref.exr    16, 64, 256, 1024 spp, each in a
                                                       fresh process: wall seconds
                                                       (start-up included), relMSE and
                                                       efficiency against ref.exr

Every render also prints one JSON line (`{"peer": "mitsuba", ...}`) for scripts.
See scripts/peers/README.md for installing Mitsuba here (and the LLVM note).

The geometry is written as binary PLY (float32, the same bits arbor computes) and
loaded with face normals, so both renderers trace the identical triangles.
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import time

# ---------------------------------------------------------------------------------------
# The scene. These numbers MUST match src/scene/builtin.rs::cornell_data (and the
# `cornell` function there): the published 556-unit Cornell box data set
# (https://www.graphics.cornell.edu/online/box/data.html), counter-clockwise quads seen
# from the side their normal cross(b - a, c - a) faces (into the room, out of the
# blocks, down for the light), triangles (0, 1, 2) and (0, 2, 3).
FLOOR = [[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]]
CEILING = [[556.0, 548.8, 0.0], [556.0, 548.8, 559.2], [0.0, 548.8, 559.2], [0.0, 548.8, 0.0]]
BACK_WALL = [[549.6, 0.0, 559.2], [0.0, 0.0, 559.2], [0.0, 548.8, 559.2], [556.0, 548.8, 559.2]]
GREEN_WALL = [[0.0, 0.0, 559.2], [0.0, 0.0, 0.0], [0.0, 548.8, 0.0], [0.0, 548.8, 559.2]]
RED_WALL = [[552.8, 0.0, 0.0], [549.6, 0.0, 559.2], [556.0, 548.8, 559.2], [556.0, 548.8, 0.0]]
LIGHT = [[343.0, 548.8, 227.0], [343.0, 548.8, 332.0], [213.0, 548.8, 332.0], [213.0, 548.8, 227.0]]
LIGHT_DROP = 0.5  # the light hangs this far (data units) under the ceiling
SHORT_BLOCK = [
    [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
    [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
    [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
    [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
    [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
]
TALL_BLOCK = [
    [[423.0, 330.0, 247.0], [265.0, 330.0, 296.0], [314.0, 330.0, 456.0], [472.0, 330.0, 406.0]],
    [[423.0, 0.0, 247.0], [423.0, 330.0, 247.0], [472.0, 330.0, 406.0], [472.0, 0.0, 406.0]],
    [[472.0, 0.0, 406.0], [472.0, 330.0, 406.0], [314.0, 330.0, 456.0], [314.0, 0.0, 456.0]],
    [[314.0, 0.0, 456.0], [314.0, 330.0, 456.0], [265.0, 330.0, 296.0], [265.0, 0.0, 296.0]],
    [[265.0, 0.0, 296.0], [265.0, 330.0, 296.0], [423.0, 330.0, 247.0], [423.0, 0.0, 247.0]],
]
EYE = [278.0, 273.0, -800.0]
LOOK_AT = [278.0, 273.0, 0.0]
UP = [0.0, 1.0, 0.0]
VFOV_DEG = 39.3076  # 2 atan(12.5 / 35): 35 mm lens, 25 mm film, spanning the height
# To arbor's frame: x' = (CENTER_X - x) * SCALE, y' = y * SCALE, z' = (CENTER_Z - z) * SCALE.
CENTER_X = 278.0
CENTER_Z = 279.6
SCALE_DIVISOR = 278.0  # SCALE = 1 / 278 in float32
WHITE = [0.73, 0.73, 0.73]
RED = [0.65, 0.05, 0.05]
GREEN = [0.12, 0.45, 0.15]
EMISSION = [17.0, 12.0, 4.0]  # radiance of the light, one-sided, facing down (-y)
WIDTH, HEIGHT = 256, 256
# The integrator: Mitsuba counts the camera segment as depth 1; arbor's path tracer
# uses the same convention.
MAX_DEPTH = 8
RR_DEPTH = 5
# ---------------------------------------------------------------------------------------

LADDER = [16, 64, 256, 1024]
REFERENCE_SPP = 8192
PASS_SPP = 256  # larger sample counts are rendered as equal passes and averaged


def f32(x):
    """Rounds to the nearest float32 (IEEE, as Rust's f32 arithmetic does)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


SCALE = f32(1.0 / SCALE_DIVISOR)


def point(p):
    """A data-set point in arbor's frame, computed in float32 exactly as
    `cornell_data::point` does (each operation rounded to float32)."""
    x, y, z = (f32(c) for c in p)
    return [f32(f32(f32(CENTER_X) - x) * SCALE), f32(y * SCALE), f32(f32(f32(CENTER_Z) - z) * SCALE)]


def lowered_light():
    return [[x, f32(f32(y) - f32(LIGHT_DROP)), z] for x, y, z in LIGHT]


def write_ply(path, quads):
    """Binary PLY of `quads`, each split into triangles (0, 1, 2) and (0, 2, 3)."""
    verts = [point(p) for q in quads for p in q]
    faces = []
    for k in range(len(quads)):
        b = 4 * k
        faces += [(b, b + 1, b + 2), (b, b + 2, b + 3)]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for v in verts:
            f.write(struct.pack("<3f", *v))
        for t in faces:
            f.write(struct.pack("<B3i", 3, *t))


def scene_dict(mi, tmp, spp, seed):
    def diffuse(rgb):
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}}

    def mesh(name, quads, bsdf, emitter=None):
        path = os.path.join(tmp, name + ".ply")
        write_ply(path, quads)
        # face_normals: shade with the geometric normal, as arbor does for meshes
        # without normals (the red wall is not planar).
        d = {"type": "ply", "filename": path, "face_normals": True, "bsdf": bsdf}
        if emitter:
            d["emitter"] = emitter
        return d

    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH, "rr_depth": RR_DEPTH, "hide_emitters": False},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": VFOV_DEG,
            "to_world": T().look_at(origin=point(EYE), target=point(LOOK_AT), up=UP),
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
            "film": {
                "type": "hdrfilm",
                "width": WIDTH,
                "height": HEIGHT,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
                "component_format": "float32",
            },
        },
        "white": mesh("white", [FLOOR, CEILING, BACK_WALL] + SHORT_BLOCK + TALL_BLOCK, diffuse(WHITE)),
        "red": mesh("red", [RED_WALL], diffuse(RED)),
        "green": mesh("green", [GREEN_WALL], diffuse(GREEN)),
        # The light reflects nothing (arbor's emissive material has no albedo); Mitsuba's
        # area emitter is one-sided, along the normal: -y here.
        "light": mesh(
            "light",
            [lowered_light()],
            diffuse([0.0, 0.0, 0.0]),
            {"type": "area", "radiance": {"type": "rgb", "value": EMISSION}},
        ),
    }


def setup_mitsuba(variant, threads):
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(variant)
    if threads:
        dr.set_thread_count(threads)
    return mi, dr


def render(variant, spp, seed, out, threads):
    """Renders in equal passes of at most PASS_SPP and averages them; returns a dict of
    figures. `seconds` counts from before Mitsuba is imported (start-up included)."""
    t0 = time.perf_counter()
    mi, dr = setup_mitsuba(variant, threads)
    passes = max(1, math.ceil(spp / PASS_SPP))
    per_pass = math.ceil(spp / passes)
    with tempfile.TemporaryDirectory(prefix="arbor-cornell-") as tmp:
        scene = mi.load_dict(scene_dict(mi, tmp, per_pass, seed))
    t_loaded = time.perf_counter()
    acc = None
    for k in range(passes):
        img = mi.render(scene, spp=per_pass, seed=seed * 100003 + k)
        acc = img if acc is None else acc + img
    acc = acc / passes
    dr.eval(acc)
    mi.Bitmap(acc).write(out)  # reads the image back: the render is finished
    t1 = time.perf_counter()
    return {
        "peer": "mitsuba",
        "variant": variant,
        "spp": per_pass * passes,
        "passes": passes,
        "seconds": None,  # filled in by the caller that timed the whole process
        "in_process_seconds": t1 - t0,
        "render_seconds": t1 - t_loaded,
        "out": out,
    }


def rel_mse(variant, image, reference):
    """mean over pixels and channels of (a - b)^2 / (b^2 + 1e-2)."""
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(variant)
    a = mi.TensorXf(mi.Bitmap(image).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32))
    b = mi.TensorXf(mi.Bitmap(reference).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32))
    if a.shape != b.shape:
        sys.exit(f"{image} is {a.shape}, reference {reference} is {b.shape}")
    d = a.array - b.array
    return float(dr.mean(d * d / (b.array * b.array + 1e-2)).array[0])


def print_table(rows):
    print(f"{'spp':>6} {'wall s':>8} {'render s':>9} {'relMSE':>11} {'efficiency':>11}")
    for r in rows:
        m = f"{r['rel_mse']:.4e}" if r.get("rel_mse") is not None else "-"
        e = f"{r['efficiency']:.4g}" if r.get("efficiency") is not None else "-"
        print(f"{r['spp']:>6} {r['seconds']:>8.2f} {r['render_seconds']:>9.2f} {m:>11} {e:>11}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, help=f"samples per pixel (default 64; {REFERENCE_SPP} with --reference)")
    ap.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant (default llvm_ad_rgb; scalar_rgb works without LLVM)")
    ap.add_argument("--out", help="output EXR (default cornell_mitsuba_<spp>.exr; a temporary file per rung with --ladder)")
    ap.add_argument("--seed", type=int, default=1, help="sampler seed (default 1)")
    ap.add_argument("--threads", type=int, default=0, help="Dr.Jit worker threads (default: all cores)")
    ap.add_argument(
        "--reference",
        nargs="?",
        const=True,
        metavar="FILE",
        help="without --ladder: render a converged reference; with --ladder FILE: compare each rung against FILE",
    )
    ap.add_argument("--ladder", action="store_true", help=f"render {', '.join(map(str, LADDER))} spp, each in a fresh process")
    ap.add_argument("--json-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()

    if args.ladder:
        ref = args.reference if isinstance(args.reference, str) else None
        if ref and not os.path.exists(ref):
            sys.exit(f"reference {ref} does not exist (make one with --reference --out {ref})")
        rows = []
        with tempfile.TemporaryDirectory(prefix="arbor-ladder-") as tmp:
            for spp in [args.spp] if args.spp else LADDER:
                out = os.path.join(tmp, f"cornell_{spp}.exr")
                cmd = [sys.executable, os.path.abspath(__file__), "--json-only", "--spp", str(spp), "--variant", args.variant,
                       "--seed", str(args.seed), "--threads", str(args.threads), "--out", out]
                t0 = time.perf_counter()
                p = subprocess.run(cmd, capture_output=True, text=True)
                seconds = time.perf_counter() - t0
                if p.returncode != 0:
                    sys.exit(f"render at {spp} spp failed:\n{p.stderr}")
                row = json.loads(p.stdout.strip().splitlines()[-1])
                row["seconds"] = seconds
                row["out"] = None
                if ref:
                    row["rel_mse"] = rel_mse(args.variant, out, ref)
                    row["efficiency"] = 1.0 / (row["rel_mse"] * seconds)
                rows.append(row)
                print(json.dumps(row), flush=True)
        print_table(rows)
        return

    spp = args.spp or (REFERENCE_SPP if args.reference else 64)
    out = args.reference if isinstance(args.reference, str) and not args.out else args.out
    out = out or f"cornell_mitsuba_{spp}.exr"
    t0 = time.perf_counter()
    row = render(args.variant, spp, args.seed, out, args.threads)
    row["seconds"] = row["in_process_seconds"] if args.json_only else time.perf_counter() - t0
    print(json.dumps(row), flush=True)
    if not args.json_only:
        print_table([row])


if __name__ == "__main__":
    main()
