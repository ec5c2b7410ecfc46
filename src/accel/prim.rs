//! Primitives as builders see them: bounds, and for "perfect splits" the exact part
//! of a primitive inside a box (triangles clipped by Sutherland–Hodgman in f64,
//! spheres by their bounding box).

use glam::{DVec3, Vec3};

use crate::math::Aabb;
use crate::scene::Scene;

/// The geometry of primitive `i` (triangles first, then spheres).
#[derive(Debug, Clone, Copy)]
pub enum PrimGeom {
    Triangle([Vec3; 3]),
    Sphere(Vec3, f32),
}

/// Geometry of primitive `i` of `scene`.
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
}
