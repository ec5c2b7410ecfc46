#!/usr/bin/env python3
"""mitsuba-check.py: arbor's microfacet materials against Mitsuba 3 (docs/materials.md).

Usage: scripts/mitsuba-check.py [--bin PATH] [--spp N] [--size WxH] [--out DIR]
                                [--quick] [--variant NAME]

Writes each scene once for arbor (TOML, OBJ quads, an EXR sky) and once for Mitsuba 3
(a dict of the same shapes and files), renders both with the path tracer and prints,
per scene, the image means and each object's mean (the pixels whose arbor primitive
AOV and their four neighbours' name that object, so silhouettes are left out), and
their ratios. A row fails when the image means differ by more than 1% or an object's
by more than 3% (issue 45's bounds); the exit status is 1 when any row fails.

Scenes (roughness 0.05, 0.2, 0.5 and 0.8 each):
  conductor   gold (complex index) sphere and plane, Lambert floor, under a sky and
              an area light; Mitsuba's roughconductor (GGX, sample_visible)
  dielectric  glass (ior 1.5) sphere and plane, the same floor and light;
              Mitsuba's roughdielectric
  furnace     a white conductor (Fresnel 1) sphere in a uniform environment of
              radiance 1: what it loses is single scattering's loss (none at
              roughness 0, which is added to this set); Mitsuba's material "none"

Needs: pip install mitsuba (scalar_rgb runs everywhere; --variant llvm_ad_rgb is
faster where Dr.Jit finds LLVM). arbor is run as it is: set VK_DRIVER_FILES for
lavapipe. Options:
  --bin PATH     the arbor binary (default target/release/arbor, else target/debug/arbor)
  --spp N        samples per pixel for both (default 512; --quick 64)
  --size WxH     image size (default 96x72; --quick 48x36)
  --out DIR      where scenes and images go (default mitsuba-check-YYYYmmdd-HHMMSS)
  --quick        roughness 0.2 and 0.8 only, small and few samples (bounds not met)
  --variant V    Mitsuba variant (default scalar_rgb)
"""

import argparse
import datetime
import os
import subprocess
import sys
import time

try:
    import numpy as np
    import mitsuba as mi
except ImportError as e:  # pragma: no cover
    sys.exit(f"mitsuba-check: error: {e} (pip install mitsuba numpy)")

GOLD_ETA = [0.143, 0.374, 1.442]
GOLD_K = [3.983, 2.385, 1.603]
MAX_DEPTH = 8


def quad_obj(path, corners):
    """An OBJ of one quad (two triangles), corners counter-clockwise seen from its front."""
    with open(path, "w") as f:
        for c in corners:
            f.write("v %g %g %g\n" % tuple(c))
        f.write("f 1 2 3\nf 1 3 4\n")


def sky_exr(path, uniform):
    """A latitude-only sky (so that the two renderers' azimuth conventions cannot
    differ): blue at the zenith, bright at the horizon, a dark ground, blended over a
    few degrees; or radiance 1 everywhere."""
    w, h = 256, 128
    img = np.ones((h, w, 3), dtype=np.float32)
    if not uniform:
        for y in range(h):
            lat = np.pi / 2 - (y + 0.5) / h * np.pi  # +pi/2 at row 0 (+y)
            s = np.sin(lat)
            sky = np.array([1.2, 1.1, 1.0]) * (1 - s) + np.array([0.3, 0.5, 1.0]) * s
            ground = np.array([0.25, 0.22, 0.18])
            t = np.clip((lat + 0.08) / 0.16, 0.0, 1.0)
            img[y, :, :] = ground * (1 - t) + sky * t
    mi.Bitmap(img).write(path)


def write_scene(d, kind, r, size):
    """Writes scene.toml for arbor and returns Mitsuba's dict of the same scene."""
    os.makedirs(d, exist_ok=True)
    w, h = size
    cam = dict(eye=[0.0, 1.2, 4.0], look_at=[0.0, 0.3, 0.0], vfov=40.0)
    furnace = kind == "furnace"
    sky_exr(os.path.join(d, "sky.exr"), furnace)
    toml = [
        "[camera]",
        "eye = %s" % cam["eye"],
        "look_at = %s" % cam["look_at"],
        "vfov = %g" % cam["vfov"],
        "[film]",
        "width = %d" % w,
        "height = %d" % h,
        "[render]",
        "max_depth = %d" % MAX_DEPTH,
        "[environment]",
        'file = "sky.exr"',
    ]
    m_scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": cam["vfov"],
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["look_at"], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
        "sky": {"type": "envmap", "filename": os.path.join(d, "sky.exr")},
    }
    if kind == "conductor":
        toml += ["[[material]]", 'name = "m"', 'type = "conductor"', "roughness = %g" % r,
                 "eta = %s" % GOLD_ETA, "k = %s" % GOLD_K]
        m_bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha": r * r, "sample_visible": True,
                  "eta": {"type": "rgb", "value": GOLD_ETA}, "k": {"type": "rgb", "value": GOLD_K}}
    elif kind == "dielectric":
        toml += ["[[material]]", 'name = "m"', 'type = "dielectric"', "roughness = %g" % r, "ior = 1.5"]
        m_bsdf = {"type": "roughdielectric", "distribution": "ggx", "alpha": r * r, "sample_visible": True,
                  "int_ior": 1.5, "ext_ior": 1.0}
    else:
        toml += ["[[material]]", 'name = "m"', 'type = "conductor"', "roughness = %g" % r, "color = [1, 1, 1]"]
        m_bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha": r * r, "sample_visible": True,
                  "material": "none"}
    if r == 0.0:
        m_bsdf = {k: v for k, v in m_bsdf.items() if k not in ("distribution", "alpha", "sample_visible")}
        m_bsdf["type"] = {"roughconductor": "conductor", "roughdielectric": "dielectric"}[m_bsdf["type"]]
    objects = []  # (name, arbor primitive ids)
    prim = 0
    if not furnace:
        toml += ["[[material]]", 'name = "floor"', 'type = "lambert"', "color = [0.6, 0.6, 0.6]",
                 "[[material]]", 'name = "lamp"', 'type = "emissive"', "emission = [8, 7.5, 7]"]
        g = 3.0
        quad_obj(os.path.join(d, "floor.obj"), [(-g, -0.5, g), (g, -0.5, g), (g, -0.5, -g), (-g, -0.5, -g)])
        quad_obj(os.path.join(d, "plane.obj"), [(0.3, -0.5, -1.2), (1.9, -0.5, -0.6), (1.9, 1.1, -0.6), (0.3, 1.1, -1.2)])
        l = 0.5
        quad_obj(os.path.join(d, "lamp.obj"), [(-l - 1, 2.5, -l), (l - 1, 2.5, -l), (l - 1, 2.5, l), (-l - 1, 2.5, l)])
        for name, mat in [("floor", "floor"), ("plane", "m"), ("lamp", "lamp")]:
            toml += ["[[mesh]]", 'file = "%s.obj"' % name, 'material = "%s"' % mat]
            objects.append((name, {prim, prim + 1}))
            prim += 2
        m_scene["floor"] = {"type": "obj", "filename": os.path.join(d, "floor.obj"),
                            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.6, 0.6, 0.6]}}}
        m_scene["plane"] = {"type": "obj", "filename": os.path.join(d, "plane.obj"), "bsdf": m_bsdf}
        m_scene["lamp"] = {"type": "obj", "filename": os.path.join(d, "lamp.obj"),
                           "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
                           "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [8, 7.5, 7]}}}
    toml += ["[[sphere]]", "center = [-0.5, 0.2, 0.0]", "radius = 0.7", 'material = "m"']
    objects.append(("sphere", {prim}))
    m_scene["sphere"] = {"type": "sphere", "center": [-0.5, 0.2, 0.0], "radius": 0.7, "bsdf": m_bsdf}
    with open(os.path.join(d, "scene.toml"), "w") as f:
        f.write("\n".join(toml) + "\n")
    return m_scene, objects


def interior(prim):
    """Pixels whose four neighbours show the same primitive group as they do."""
    p = prim
    keep = np.ones(p.shape, dtype=bool)
    keep[1:, :] &= p[1:, :] == p[:-1, :]
    keep[:-1, :] &= p[:-1, :] == p[1:, :]
    keep[:, 1:] &= p[:, 1:] == p[:, :-1]
    keep[:, :-1] &= p[:, :-1] == p[:, 1:]
    return keep


def lum(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def main():
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("--bin")
    ap.add_argument("--spp", type=int)
    ap.add_argument("--size")
    ap.add_argument("--out")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("-h", "--help", action="store_true")
    try:
        a = ap.parse_args()
    except SystemExit:
        sys.exit(2)
    if a.help:
        print(__doc__.strip())
        return 0
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    binary = a.bin or next((p for p in (os.path.join(root, "target/release/arbor"), os.path.join(root, "target/debug/arbor"))
                            if os.path.exists(p)), None)
    if not binary or not os.path.exists(binary):
        print("mitsuba-check: error: no arbor binary (cargo build --release, or --bin PATH)", file=sys.stderr)
        return 2
    spp = a.spp or (64 if a.quick else 512)
    try:
        w, h = (int(x) for x in (a.size or ("48x36" if a.quick else "96x72")).split("x"))
    except ValueError:
        print("mitsuba-check: error: --size must be WxH", file=sys.stderr)
        return 2
    out = a.out or datetime.datetime.now().strftime("mitsuba-check-%Y%m%d-%H%M%S")
    try:
        mi.set_variant(a.variant)
    except Exception as e:
        print(f"mitsuba-check: error: Mitsuba variant {a.variant}: {e}", file=sys.stderr)
        return 2
    rough = [0.2, 0.8] if a.quick else [0.05, 0.2, 0.5, 0.8]
    cases = [(k, r) for k in ("conductor", "dielectric") for r in rough] + [("furnace", r) for r in [0.0] + rough]
    print(f"arbor {binary}, Mitsuba {mi.__version__} {a.variant}, {w}x{h}, {spp} spp, max depth {MAX_DEPTH}, into {out}")
    print("| scene | roughness | image arbor | image Mitsuba | ratio | objects (arbor / Mitsuba) | |")
    print("|---|---|---|---|---|---|---|")
    failed = 0
    for kind, r in cases:
        d = os.path.join(out, f"{kind}-{r}")
        m_scene, objects = write_scene(d, kind, r, (w, h))
        t0 = time.time()
        cmd = [binary, "render", os.path.join(d, "scene.toml"), "--spp", str(spp), "--seed", "1",
               "-o", os.path.join(d, "arbor.exr"), "--aov", "prim=" + os.path.join(d, "prim.exr")]
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            print(f"mitsuba-check: error: arbor failed on {d}: {run.stderr.strip()}", file=sys.stderr)
            return 1
        ta = time.time() - t0
        t0 = time.time()
        img_m = np.array(mi.render(mi.load_dict(m_scene), spp=spp, seed=1), dtype=np.float64)
        mi.Bitmap(img_m.astype(np.float32)).write(os.path.join(d, "mitsuba.exr"))
        tm = time.time() - t0
        img_a = np.array(mi.Bitmap(os.path.join(d, "arbor.exr")), dtype=np.float64)[..., :3]
        prim = np.array(mi.Bitmap(os.path.join(d, "prim.exr")), dtype=np.float64)[..., 0]
        la, lm = lum(img_a), lum(img_m)
        ratio = la.mean() / lm.mean()
        ok = abs(ratio - 1) <= 0.01
        group = np.full(prim.shape, -1)
        for i, (_, ids) in enumerate(objects):
            for p in ids:
                group[prim == p] = i
        keep = interior(group)
        parts = []
        for i, (name, _) in enumerate(objects):
            sel = keep & (group == i)
            if sel.sum() < 10:
                continue
            ra = la[sel].mean() / max(lm[sel].mean(), 1e-12)
            ok &= abs(ra - 1) <= 0.03
            parts.append(f"{name} {la[sel].mean():.4f} / {lm[sel].mean():.4f} = {ra:.3f}")
        failed += not ok
        print(f"| {kind} | {r} | {la.mean():.4f} | {lm.mean():.4f} | {ratio:.4f} | {'; '.join(parts)} | "
              f"{'ok' if ok else 'FAILS'} ({ta:.0f} s / {tm:.0f} s) |", flush=True)
    print(f"{len(cases) - failed} of {len(cases)} within the bounds (image 1%, objects 3%)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
