//! Primitives as builders see them: bounds, and for "perfect splits" the exact part
//! of a primitive inside a box (triangles clipped by Sutherland–Hodgman in f64,
//! spheres by their bounding box).

use glam::{DVec3, Vec3};

use crate::math::intersect::{ray_sphere, ray_triangle, IntersectMode};
use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// What CPU traversal tests rays against: the scene's primitives (triangles first, then
/// spheres) with the ray/triangle test the render uses. The intersection mode is a
/// render setting, not part of the scene.
#[derive(Debug, Clone, Copy)]
pub struct Prims<'a> {
    pub scene: &'a Scene,
    pub mode: IntersectMode,
    /// The scene whose materials and textures the alpha test reads (`scene` itself,
    /// or for an instance's prototype the scene that holds it), and whether any of
    /// its materials has alpha (crate::scene::alpha).
    pub shading: &'a Scene,
    pub alpha: bool,
}

impl<'a> Prims<'a> {
    /// The scene's primitives with the watertight ray/triangle test (the default).
    pub fn new(scene: &'a Scene) -> Prims<'a> {
        Self::with_mode(scene, IntersectMode::Watertight)
    }

    /// The scene's primitives with the ray/triangle test `mode`.
    pub fn with_mode(scene: &'a Scene, mode: IntersectMode) -> Prims<'a> {
        Prims { scene, mode, shading: scene, alpha: scene.has_alpha() }
    }

    /// An instance's prototype `geometry`, shaded (and alpha-tested) as this scene.
    pub fn prototype(&self, geometry: &'a Scene) -> Prims<'a> {
        Prims { scene: geometry, ..*self }
    }
}

/// Tests primitive `prim` against `ray` clipped to the best hit so far, and records it
/// if it wins. Twin of `intersect_triangle` / `intersect_sphere` in trace.comp.
#[inline]
pub fn intersect_prim(prims: &Prims, prim: u32, ray: &Ray, best: &mut Hit) -> bool {
    let scene = prims.scene;
    let nt = scene.triangles.len() as u32;
    let r = Ray { tmax: best.t, ..*ray };
    if prim < nt {
        let [a, b, c] = scene.triangles[prim as usize].map(|k| scene.positions[k as usize]);
        if let Some((t, u, v)) = ray_triangle(&r, a, b, c, prims.mode) {
            let meets =
                || !prims.alpha || crate::scene::alpha::meets(prims.shading, scene, prim, ray.origin, ray.dir, u, v);
            if best.closer(t, prim) && meets() {
                *best = Hit { t, prim, u, v };
                return true;
            }
        }
    } else {
        let s = &scene.spheres[(prim - nt) as usize];
        if let Some(t) = ray_sphere(&r, s.center, s.radius) {
            let meets = || {
                !prims.alpha || crate::scene::alpha::meets_sphere(prims.shading, s.material, prim, ray.origin, ray.dir)
            };
            if best.closer(t, prim) && meets() {
                *best = Hit { t, prim, u: 0.0, v: 0.0 };
                return true;
            }
        }
    }
    false
}

/// The geometry of primitive `i` (triangles first, then spheres).
#[derive(Debug, Clone, Copy)]
pub enum PrimGeom {
    Triangle([Vec3; 3]),
    Sphere(Vec3, f32),
}

/// Geometry of primitive `i` of `scene`. Inlined: the builders' bounds pass over a
/// million triangles took 6.7–6.8 ms with it called, 1.9–2.0 inlined (docs/build-notes.md,
/// "Release builds: one codegen unit").
#[inline]
pub fn geom(scene: &Scene, i: u32) -> PrimGeom {
    let nt = scene.triangles.len() as u32;
    if i < nt {
        PrimGeom::Triangle(scene.triangles[i as usize].map(|k| scene.positions[k as usize]))
    } else {
        let s = &scene.spheres[(i - nt) as usize];
        PrimGeom::Sphere(s.center, s.radius)
    }
}

/// The bounding box of a primitive.
#[inline]
pub fn bounds(g: &PrimGeom) -> Aabb {
    match *g {
        PrimGeom::Triangle([a, b, c]) => Aabb { min: a.min(b).min(c), max: a.max(b).max(c) },
        PrimGeom::Sphere(c, r) => Aabb { min: c - Vec3::splat(r), max: c + Vec3::splat(r) },
    }
}

/// Intersection of two boxes, None when empty.
pub fn intersect_boxes(a: &Aabb, b: &Aabb) -> Option<Aabb> {
    let r = Aabb { min: a.min.max(b.min), max: a.max.min(b.max) };
    (!r.is_empty()).then_some(r)
}

/// Bounds of the part of `g` inside `b`: the exact clipped triangle when `exact`,
/// else the primitive's box intersected with `b`. None when nothing is inside.
pub fn clipped_bounds(g: &PrimGeom, b: &Aabb, exact: bool) -> Option<Aabb> {
    match g {
        PrimGeom::Triangle(v) if exact => clip_triangle(v, b),
        _ => intersect_boxes(&bounds(g), b),
    }
}

/// Clips a triangle to a box (Sutherland–Hodgman against its six planes, in f64) and
/// returns the bounds of what remains, rounded outward to f32 and limited to the box.
pub fn clip_triangle(v: &[Vec3; 3], b: &Aabb) -> Option<Aabb> {
    // A triangle inside the box clips to itself (the common case: most are far from
    // the planes); one outside a plane clips to nothing.
    let (tmin, tmax) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
    if tmin.cmpge(b.min).all() && tmax.cmple(b.max).all() {
        return Some(Aabb { min: tmin, max: tmax });
    }
    if tmax.cmplt(b.min).any() || tmin.cmpgt(b.max).any() {
        return None;
    }
    // A triangle clipped by 6 planes has at most 9 vertices.
    let mut poly = [DVec3::ZERO; 9];
    let mut next = [DVec3::ZERO; 9];
    let (mut len, mut next_len);
    for (k, p) in v.iter().enumerate() {
        poly[k] = p.as_dvec3();
    }
    len = 3;
    for axis in 0..3 {
        for (bound, keep_above) in [(f64::from(b.min[axis]), true), (f64::from(b.max[axis]), false)] {
            let inside = |p: &DVec3| if keep_above { p[axis] >= bound } else { p[axis] <= bound };
            // A plane every vertex is inside of leaves the polygon as it is.
            if poly[..len].iter().all(inside) {
                continue;
            }
            next_len = 0;
            for i in 0..len {
                let cur = poly[i];
                let prev = poly[(i + len - 1) % len];
                let (ci, pi) = (inside(&cur), inside(&prev));
                if ci != pi && next_len < 9 {
                    let t = (bound - prev[axis]) / (cur[axis] - prev[axis]);
                    let mut x = prev + (cur - prev) * t;
                    x[axis] = bound;
                    next[next_len] = x;
                    next_len += 1;
                }
                if ci && next_len < 9 {
                    next[next_len] = cur;
                    next_len += 1;
                }
            }
            std::mem::swap(&mut poly, &mut next);
            len = next_len;
            if len == 0 {
                return None;
            }
        }
    }
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in &poly[..len] {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    // Round outward, then stay inside the box.
    let down = |x: f64| {
        let f = x as f32;
        if f64::from(f) > x {
            f.next_down()
        } else {
            f
        }
    };
    let up = |x: f64| {
        let f = x as f32;
        if f64::from(f) < x {
            f.next_up()
        } else {
            f
        }
    };
    let r = Aabb {
        min: Vec3::new(down(lo.x), down(lo.y), down(lo.z)).max(b.min),
        max: Vec3::new(up(hi.x), up(hi.y), up(hi.z)).min(b.max),
    };
    (!r.is_empty()).then_some(r)
}

/// `b` grown by a relative 1e-5 of its extent and at least 8 ulps of its coordinates
/// (the twin of `kdtree::shrink`). Grids and octrees insert a primitive into every cell
/// whose grown box it overlaps, so that a hit lying on (or within rounding of) a cell
/// face is listed on both sides and traversal may enter either.
pub fn grow(b: &Aabb) -> Aabb {
    let mag = b.min.abs().max(b.max.abs());
    let pad = (b.extent() * 1e-5).max(mag * 1e-6).max(Vec3::splat(1e-30));
    Aabb { min: b.min - pad, max: b.max + pad }
}

/// Whether the primitive touches the closed box `b`: the separating axis test of
/// Akenine-Moller (2001) for triangles (box normals, triangle normal, the nine edge
/// cross products), the closest-point distance for spheres (Arvo 1990). Evaluated in
/// f64 from the f32 inputs, so the answer is exact up to a relative 1e-15: callers
/// pass boxes grown by [`grow`], far larger than that.
pub fn overlaps(g: &PrimGeom, b: &Aabb) -> bool {
    if b.is_empty() {
        return false;
    }
    let lo = b.min.as_dvec3();
    let hi = b.max.as_dvec3();
    match *g {
        PrimGeom::Sphere(c, r) => {
            let c = c.as_dvec3();
            let d = c - c.clamp(lo, hi);
            let r = f64::from(r);
            d.length_squared() <= r * r
        }
        PrimGeom::Triangle(v) => {
            let (tmin, tmax) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
            if tmax.cmplt(b.min).any() || tmin.cmpgt(b.max).any() {
                return false;
            }
            if tmin.cmpge(b.min).all() && tmax.cmple(b.max).all() {
                return true;
            }
            let c = (lo + hi) * 0.5;
            let h = (hi - lo) * 0.5;
            let p = [v[0].as_dvec3() - c, v[1].as_dvec3() - c, v[2].as_dvec3() - c];
            let e = [p[1] - p[0], p[2] - p[1], p[0] - p[2]];
            // Separated along `axis` when the triangle's projection misses the box's.
            let separated = |axis: DVec3| {
                let (a, b2, c2) = (axis.dot(p[0]), axis.dot(p[1]), axis.dot(p[2]));
                let r = h.x * axis.x.abs() + h.y * axis.y.abs() + h.z * axis.z.abs();
                a.min(b2).min(c2) > r || a.max(b2).max(c2) < -r
            };
            if separated(e[0].cross(e[1])) {
                return false;
            }
            for edge in e {
                for unit in [DVec3::X, DVec3::Y, DVec3::Z] {
                    if separated(edge.cross(unit)) {
                        return false;
                    }
                }
            }
            true
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_keeps_inside_part() {
        let tri = [Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0)];
        let b = Aabb { min: Vec3::new(0.0, -1.0, -1.0), max: Vec3::new(2.0, 3.0, 1.0) };
        let c = clip_triangle(&tri, &b).expect("overlaps");
        assert_eq!(c.min.x, 0.0);
        assert_eq!(c.max.x, 1.0);
        assert!((c.max.y - 2.0).abs() < 1e-6);
        let far = Aabb { min: Vec3::splat(5.0), max: Vec3::splat(6.0) };
        assert!(clip_triangle(&tri, &far).is_none());
    }

    #[test]
    fn clip_of_a_corner_cut_is_tighter_than_the_box() {
        // The triangle crosses the box corner region only partly.
        let tri = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)];
        let b = Aabb { min: Vec3::new(2.0, 1.0, -1.0), max: Vec3::new(4.0, 4.0, 1.0) };
        let c = clip_triangle(&tri, &b).expect("overlaps");
        assert!((c.max.y - 2.0).abs() < 1e-6, "{c:?}");
    }

    #[test]
    fn overlap_test_separates_by_edges_and_planes() {
        let tri = PrimGeom::Triangle([Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)]);
        // Inside the triangle's box but beyond its hypotenuse: only an edge axis separates.
        let beyond = Aabb { min: Vec3::new(2.5, 2.5, -1.0), max: Vec3::new(3.0, 3.0, 1.0) };
        assert!(!overlaps(&tri, &beyond));
        // Touching the hypotenuse at (2, 2) counts.
        let touching = Aabb { min: Vec3::new(2.0, 2.0, -1.0), max: Vec3::new(3.0, 3.0, 1.0) };
        assert!(overlaps(&tri, &touching));
        // Above the plane z = 0.
        let above = Aabb { min: Vec3::new(0.5, 0.5, 0.1), max: Vec3::new(1.0, 1.0, 1.0) };
        assert!(!overlaps(&tri, &above));
        let sphere = PrimGeom::Sphere(Vec3::ZERO, 1.0);
        let corner = Aabb { min: Vec3::splat(0.6), max: Vec3::splat(2.0) };
        assert!(!overlaps(&sphere, &corner), "0.6 * sqrt(3) > 1");
        let near = Aabb { min: Vec3::splat(0.5), max: Vec3::splat(2.0) };
        assert!(overlaps(&sphere, &near));
    }

    #[test]
    fn overlap_agrees_with_clipping_on_random_boxes() {
        let mut s = 12345u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32 * 4.0 - 2.0
        };
        for _ in 0..20_000 {
            let tri = [Vec3::new(rnd(), rnd(), rnd()), Vec3::new(rnd(), rnd(), rnd()), Vec3::new(rnd(), rnd(), rnd())];
            let (a, b) = (Vec3::new(rnd(), rnd(), rnd()), Vec3::new(rnd(), rnd(), rnd()));
            let bx = Aabb { min: a.min(b), max: a.max(b) };
            let sat = overlaps(&PrimGeom::Triangle(tri), &bx);
            // Clipping to a slightly shrunk box never finds overlap the test denies, and
            // clipping to a slightly grown box always finds overlap the test reports.
            if !sat {
                assert!(clip_triangle(&tri, &crate::accel::kdtree::shrink(&bx)).is_none(), "{tri:?} {bx:?}");
            } else {
                assert!(clip_triangle(&tri, &grow(&bx)).is_some(), "{tri:?} {bx:?}");
            }
        }
    }
}
