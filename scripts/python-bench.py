#!/usr/bin/env python3
"""arbor's Python module against Open3D and trimesh + embreex, in one run.

For each mesh (arbor's builtin:blob at 100k and 1M triangles by default) it casts 1M
camera rays and 1M random rays through:
  - arbor.RaycastingScene (the device arbor picks, or --device), every structure in
    --accel;
  - open3d.t.geometry.RaycastingScene (Embree on all the machine's cores);
  - trimesh's RayMeshIntersector through embreex, where installed;
and prints, per mesh and ray set, each tracer's rays per second (median of --repeat
casts), arbor's rate over Open3D's, and how far the hits agree with Open3D's (primitive
ids on rays both hit, t_hit within 1e-5 relative). With --example it also runs the Rust
example trace_rays on the same rays (written to a file) to compare the binding's cost.

    .venv/bin/pip install open3d-cpu trimesh embreex      # peers: benchmarks only
    .venv/bin/python scripts/python-bench.py [--meshes 100000,1000000] [--rays 1000000]
        [--accel bvh-sah] [--repeat 3] [--example target/release/examples/trace_rays]

Peers that are not installed are named and left out; arbor is required.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

import arbor


def camera_rays(v: np.ndarray, n: int) -> np.ndarray:
    """A pinhole camera looking at the mesh's box from outside: sqrt(n) x sqrt(n)."""
    lo, hi = v.min(0), v.max(0)
    center, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    eye = center + np.array([0.3, 0.4, 1.0]) / np.linalg.norm([0.3, 0.4, 1.0]) * radius * 2.2
    fwd = (center - eye) / np.linalg.norm(center - eye)
    right = np.cross(fwd, [0, 1, 0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    side = int(np.sqrt(n))
    s = np.linspace(-0.5, 0.5, side) * 0.9
    x, y = np.meshgrid(s, -s)
    d = fwd + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(eye, d.shape)
    return np.concatenate([o, d], 1).astype(np.float32)


def random_rays(v: np.ndarray, n: int, seed: int = 1) -> np.ndarray:
    """Half from outside the box towards a point in it, half from inside anywhere."""
    rng = np.random.default_rng(seed)
    lo, hi = v.min(0), v.max(0)
    center, radius = (lo + hi) / 2, np.linalg.norm(hi - lo)
    inside = rng.uniform(lo, hi, size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = inside.copy()
    half = n // 2
    o[:half] = center + d[:half] * radius
    d[:half] = inside[:half] - o[:half]
    d[:half] /= np.linalg.norm(d[:half], axis=1, keepdims=True)
    return np.concatenate([o, d], 1).astype(np.float32)


def median_rate(cast, rays: np.ndarray, repeat: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = cast(rays)
        times.append(time.perf_counter() - t0)
    return len(rays) / float(np.median(times)), out


def open3d_tracer(v: np.ndarray, t: np.ndarray):
    try:
        import open3d as o3d
    except ImportError as e:
        print(f"open3d: not installed ({e}); pip install open3d-cpu", file=sys.stderr)
        return None
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(t.astype(np.uint32)))

    def cast(rays):
        r = scene.cast_rays(o3d.core.Tensor(rays))
        return r["t_hit"].numpy(), r["primitive_ids"].numpy()

    return cast


def trimesh_tracer(v: np.ndarray, t: np.ndarray):
    try:
        import trimesh
        from trimesh.ray import ray_pyembree
    except ImportError as e:
        print(f"trimesh + embreex: not installed ({e}); pip install trimesh embreex", file=sys.stderr)
        return None
    mesh = trimesh.Trimesh(vertices=v, faces=t, process=False)
    caster = ray_pyembree.RayMeshIntersector(mesh)

    def cast(rays):
        index_tri, index_ray, loc = caster.intersects_id(
            rays[:, :3], rays[:, 3:], multiple_hits=False, return_locations=True
        )
        prim = np.full(len(rays), arbor.INVALID_ID, np.uint32)
        prim[index_ray] = index_tri
        th = np.full(len(rays), np.inf, np.float32)
        th[index_ray] = np.linalg.norm(loc - rays[index_ray, :3], axis=1)
        return th, prim

    return cast


def agreement(a: tuple, b: tuple) -> tuple[float, float, int]:
    """Over rays both hit: the share with the same primitive, and with t_hit within
    1e-5 relative; and how many rays only one of the two hits."""
    ta, pa = a
    tb, pb = b
    both = np.isfinite(ta) & np.isfinite(tb)
    same = (pa[both] == pb[both]).mean() if both.any() else 1.0
    close = (np.abs(ta[both] - tb[both]) <= 1e-5 * np.maximum(np.abs(tb[both]), 1e-6)).mean() if both.any() else 1.0
    return float(same), float(close), int((np.isfinite(ta) != np.isfinite(tb)).sum())


def example_rate(binary: str, scene: str, accel: str, rays: np.ndarray) -> float | None:
    with tempfile.NamedTemporaryFile(suffix=".f32", delete=False) as f:
        f.write(np.ascontiguousarray(rays, "<f4").tobytes())
        path = f.name
    try:
        out = subprocess.run(
            [binary, scene, "--accel", accel, "--rays-file", path], capture_output=True, text=True, check=True
        ).stdout
    finally:
        os.unlink(path)
    # A cast of the module uploads the scene and traces: the example's setup plus wall.
    m = re.search(r"wall ([0-9.]+) ms after a setup of ([0-9.]+) ms", out)
    return len(rays) / ((float(m.group(1)) + float(m.group(2))) / 1e3) if m else None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--meshes", default="100000,1000000", help="triangle counts of builtin:blob meshes")
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--accel", default="bvh-sah", help="arbor structures, comma-separated")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--device", default=None)
    ap.add_argument("--example", default=None, help="a trace_rays binary to run on the same rays")
    a = ap.parse_args()
    dev = arbor.devices()
    print(f"device: {dev[0]['name'] if dev else 'none'} ({dev[0]['driver'] if dev else ''}); cores {os.cpu_count()}")
    print("mesh | rays | tracer | Mrays/s | vs Open3D | same prim | t within 1e-5 | hit by one only")
    for tris in (int(x) for x in a.meshes.split(",")):
        source = f"builtin:blob:{tris}"
        v, t = arbor.mesh_arrays(arbor.load(source))
        tracers = {}
        for kind in a.accel.split(","):
            s = arbor.RaycastingScene(accel=kind, device=a.device)
            s.add_triangles(v, t)
            s.build()

            def cast(rays, s=s):
                r = s.cast_rays(rays)
                return r["t_hit"], r["primitive_ids"]

            tracers[f"arbor {kind}"] = cast
        for name, make in (("open3d", open3d_tracer), ("trimesh+embreex", trimesh_tracer)):
            c = make(v, t)
            if c is not None:
                tracers[name] = c
        for label, rays in (("camera", camera_rays(v, a.rays)), ("random", random_rays(v, a.rays))):
            results = {name: median_rate(cast, rays, a.repeat) for name, cast in tracers.items()}
            base = results.get("open3d")
            for name, (rate, out) in results.items():
                ratio = f"{rate / base[0]:.2f}" if base else "-"
                same, close, one = agreement(out, base[1]) if base and name != "open3d" else (1.0, 1.0, 0)
                agree = f"{100 * same:.4f}% | {100 * close:.4f}% | {one}" if base and name != "open3d" else "- | - | -"
                print(f"{len(t)} | {label} {len(rays)} | {name} | {rate / 1e6:.3f} | {ratio} | {agree}")
            if a.example:
                for kind in a.accel.split(","):
                    r = example_rate(a.example, source, kind, rays)
                    py = results[f"arbor {kind}"][0]
                    if r:
                        print(f"{len(t)} | {label} {len(rays)} | trace_rays example {kind} (setup + wall) | {r / 1e6:.3f} | "
                              f"python / example {py / r:.3f}")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
