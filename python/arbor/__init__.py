"""arbor: ray casting and rendering through arbor's acceleration structures, on any
Vulkan device (a GPU, or Mesa's lavapipe on the CPU).

The ray-casting names are Open3D's (``open3d.t.geometry.RaycastingScene``), so that code
ports by changing an import::

    import arbor
    scene = arbor.RaycastingScene()                 # accel="auto", build="cpu"
    mesh = scene.add_triangles(vertices, triangles)  # (V, 3) floats, (F, 3) integers
    hits = scene.cast_rays(rays)                     # (..., 6): origin, direction
    hits["t_hit"], hits["primitive_ids"], hits["primitive_normals"]

Device work runs with the GIL released; Ctrl-C raises ``KeyboardInterrupt`` between
pieces of a cast and between sample waves of a render. Bad input raises ``ValueError``
naming the first bad row; no device, or a device failure, ``RuntimeError``. The Vulkan
loader is opened on the first device call, not at import. docs/python.md has the rest.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any

import numpy as np

from . import _arbor

__version__: str = _arbor.__version__

#: ``geometry_ids`` and ``primitive_ids`` of a ray that hits nothing (2^32 - 1).
INVALID_ID: int = _arbor.INVALID_ID

__all__ = [
    "INVALID_ID",
    "RaycastingScene",
    "Scene",
    "devices",
    "load",
    "mesh_arrays",
    "read_image",
    "render",
    "structures",
]

Scene = _arbor.Scene


def mesh_arrays(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """A loaded scene's triangles: vertices (V, 3) float32 and triangles (F, 3) uint32,
    ready for ``RaycastingScene.add_triangles`` (instances drawn out as copies)."""
    v, t = scene.mesh()
    return v.reshape(-1, 3), t.reshape(-1, 3)


def devices() -> list[dict[str, Any]]:
    """The Vulkan devices arbor can use, in the loader's order: ``index``, ``name``,
    ``driver``, ``type`` (discrete, integrated, virtual or cpu), ``api_version``,
    ``subgroup_size`` and ``ray_query`` (whether ``accel="rayquery"`` runs there).

    Raises ``RuntimeError`` naming the loader when there is no Vulkan loader."""
    out = []
    for d in json.loads(_arbor.devices()):
        out.append(
            {
                "index": d["index"],
                "name": d["name"],
                "driver": d["driver"],
                "type": d["kind"],
                "api_version": d["api_version"],
                "subgroup_size": d["subgroup_size"],
                "ray_query": d["ray_query_missing"] is None,
            }
        )
    return out


def structures() -> list[str]:
    """The structure names ``accel=`` takes (besides ``"auto"``), as ``arbor info``
    lists them."""
    return list(_arbor.STRUCTURES)


def _real_rows(name: str, a: Any, width: int) -> tuple[np.ndarray, tuple[int, ...]]:
    """``a`` as C-contiguous float32 rows of ``width``, and the shape before the last
    axis. Any real dtype is converted; strided arrays are copied."""
    a = np.asarray(a)
    if a.dtype.kind not in "fiu":
        raise ValueError(f"{name} must hold real numbers, got dtype {a.dtype}")
    if a.ndim < 1 or a.shape[-1] != width:
        raise ValueError(f"{name} must have shape (..., {width}), got {a.shape}")
    lead = a.shape[:-1]
    return np.ascontiguousarray(a.reshape(-1, width), dtype=np.float32), lead


def _mesh_arrays(mesh: Any) -> tuple[Any, Any]:
    """(vertices, triangles) of a mesh object: trimesh's ``vertices``/``faces``, Open3D's
    legacy ``vertices``/``triangles`` or tensor ``vertex.positions``/``triangle.indices``."""
    if hasattr(mesh, "faces") and hasattr(mesh, "vertices"):
        return mesh.vertices, mesh.faces
    if hasattr(mesh, "triangles") and hasattr(mesh, "vertices"):
        return np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    if hasattr(mesh, "vertex") and hasattr(mesh, "triangle"):
        return mesh.vertex.positions.numpy(), mesh.triangle.indices.numpy()
    raise ValueError(
        f"add_triangles takes (vertices, triangles) arrays or a mesh with vertices and faces; got {type(mesh).__name__}"
    )


class RaycastingScene:
    """A scene of triangle meshes and spheres to cast rays into.

    ``accel``: a structure name (``arbor.structures()``) or ``"auto"``, which lets the
    cost model pick when the structure is built. ``build``: ``"cpu"`` (every structure)
    or ``"gpu"`` (lbvh, trbvh, bvh4, bvh8, built in Vulkan compute). ``device``: an index
    or part of a name (``arbor.devices()``); None picks the first discrete GPU, else the
    first device.

    The structure is built on the first cast or by ``build()``, and again after more
    geometry is added. A scene may be used from several threads: its calls take turns.
    """

    def __init__(self, accel: str = "auto", build: str = "cpu", device: str | int | None = None) -> None:
        self._scene = _arbor.RaycastingScene(accel, build, None if device is None else str(device))
        self._stats: dict[str, Any] | None = None

    @property
    def accel(self) -> str | None:
        """The structure's name: the one asked for, or auto's choice once built."""
        return self._scene.accel

    def add_triangles(self, vertices: Any, triangles: Any = None) -> int:
        """Adds a mesh; its geometry id. ``vertices``: (V, 3) real numbers (float64 is
        converted to float32); ``triangles``: (F, 3) integer indices into them. A mesh
        object (trimesh, Open3D) may be passed alone."""
        if triangles is None:
            vertices, triangles = _mesh_arrays(vertices)
        v, _ = _real_rows("vertices", vertices, 3)
        if v.ndim != 2 or np.asarray(vertices).ndim != 2:
            raise ValueError(f"vertices must have shape (V, 3), got {np.asarray(vertices).shape}")
        t = np.asarray(triangles)
        if t.dtype.kind not in "iu":
            raise ValueError(f"triangles must hold integers, got dtype {t.dtype}")
        if t.ndim != 2 or t.shape[1] != 3:
            raise ValueError(f"triangles must have shape (F, 3), got {t.shape}")
        if t.size:
            bad = (t < 0).any(axis=1) | (t >= len(v)).any(axis=1)
            if bad.any():
                row = int(np.argmax(bad))
                raise ValueError(
                    f"triangles row {row} is {t[row].tolist()}: an index is out of range (there are {len(v)} vertices)"
                )
        self._stats = None
        return self._scene.add_triangles(v, np.ascontiguousarray(t, dtype=np.uint32))

    def add_sphere(self, center: Any, radius: float) -> int:
        """Adds a sphere (arbor's analytic primitive); its geometry id."""
        c = np.asarray(center, dtype=np.float64).reshape(-1)
        if c.shape != (3,):
            raise ValueError(f"center must be 3 numbers, got shape {np.asarray(center).shape}")
        self._stats = None
        return self._scene.add_sphere([float(x) for x in c], float(radius))

    def build(self) -> dict[str, Any]:
        """Builds the structure now (a cast does it too); its statistics: ``kind``,
        ``build_ms``, ``bytes``, ``nodes``, ``leaves``, ``depth``, ``sah_cost`` and
        more, as ``arbor info`` prints them."""
        self._stats = json.loads(self._scene.build())
        return self._stats

    @property
    def stats(self) -> dict[str, Any]:
        """The build statistics (building first if needed)."""
        return self._stats if self._stats is not None else self.build()

    def cast_rays(self, rays: Any, *, device: bool = True) -> dict[str, np.ndarray]:
        """The closest hit of each ray. ``rays``: (..., 6) real numbers, origin then
        direction (any length but zero; ``t_hit`` is in its units).

        Returns a dict of arrays shaped like the rays: ``t_hit`` (inf on a miss),
        ``geometry_ids`` and ``primitive_ids`` (``INVALID_ID`` on a miss),
        ``primitive_uvs`` (..., 2) and ``primitive_normals`` (..., 3), unit geometric
        normals. ``device=False`` traces on the CPU with arbor's reference traversal
        of the same structure."""
        flat, lead = _real_rows("rays", rays, 6)
        t, g, p, uv, n = self._scene.cast_rays(flat, not device)
        return {
            "t_hit": t.reshape(lead),
            "geometry_ids": g.reshape(lead),
            "primitive_ids": p.reshape(lead),
            "primitive_uvs": uv.reshape(lead + (2,)),
            "primitive_normals": n.reshape(lead + (3,)),
        }

    def test_occlusions(self, rays: Any, tnear: float = 0.0, tfar: float = np.inf) -> np.ndarray:
        """Whether anything lies along each ray between ``tnear`` and ``tfar`` (in
        units of the ray's direction): a bool array shaped like the rays."""
        flat, lead = _real_rows("rays", rays, 6)
        return self._scene.test_occlusions(flat, float(tnear), float(tfar)).reshape(lead)

    def __repr__(self) -> str:
        return f"arbor.RaycastingScene(accel={self.accel!r})"


def load(path: str | os.PathLike[str]) -> Scene:
    """Reads a scene: an OBJ, PLY, OFF or glTF mesh, a scene TOML, or ``builtin:NAME``.
    What the loader dropped or approximated is issued as warnings."""
    scene = _arbor.load(os.fspath(path))
    for w in scene.warnings:
        warnings.warn(w, stacklevel=2)
    return scene


def render(
    scene: Scene | str | os.PathLike[str],
    width: int | None = None,
    height: int | None = None,
    spp: int = 16,
    integrator: str = "path",
    accel: str = "auto",
    seed: int = 0,
    aovs: bool = False,
    max_depth: int | None = None,
    device: str | int | None = None,
) -> np.ndarray | tuple[np.ndarray, dict[str, np.ndarray]]:
    """Renders a scene (or a path ``load`` reads) as ``arbor render`` does: a (H, W, 3)
    float32 linear image, the same as the command line's for the same scene, size,
    samples, integrator, structure and seed. ``width``/``height`` default to the
    scene's own size. ``integrator``: ``path``, ``whitted`` or ``sppm`` (``spp`` is then
    its iterations).

    With ``aovs=True``, also a dict: ``depth`` (H, W; inf on a miss), ``normal`` and
    ``albedo`` (H, W, 3), ``prim`` (H, W; ``INVALID_ID`` on a miss), ``variance`` and
    ``samples`` (H, W), and ``accel``, the structure used."""
    if not isinstance(scene, Scene):
        scene = load(scene)
    r = _arbor.render(
        scene, width, height, int(spp), integrator, accel, int(seed), max_depth, None if device is None else str(device)
    )
    h, w = r["height"], r["width"]
    image = r["image"].reshape(h, w, 3)
    if not aovs:
        return image
    return image, {
        "depth": r["depth"].reshape(h, w),
        "normal": r["normal"].reshape(h, w, 3),
        "albedo": r["albedo"].reshape(h, w, 3),
        "prim": r["prim"].reshape(h, w),
        "variance": r["variance"].reshape(h, w),
        "samples": r["samples"].reshape(h, w),
        "accel": r["accel"],
    }


def read_image(path: str | os.PathLike[str]) -> np.ndarray:
    """An image file (EXR, PFM, HDR, PNG, JPEG) as a (H, W, 3) float32 linear image:
    what ``arbor render`` wrote, for instance."""
    w, h, flat = _arbor.read_image(os.fspath(path))
    return flat.reshape(h, w, 3)
