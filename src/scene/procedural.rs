//! Procedural meshes, so that tests and benchmarks need no files: a displaced
//! latitude/longitude sphere ("blob") of any triangle count, and a flat quad.

use glam::Vec3;

use super::mesh::MeshData;

/// A small deterministic hash to noise, in [-1, 1].
fn hash_noise(x: i32, y: i32, seed: u32) -> f32 {
    let mut h =
        (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841) ^ seed.wrapping_mul(0xcb1a_b31f);
    h ^= h >> 13;
    h = h.wrapping_mul(0x5bd1_e995);
    h ^= h >> 15;
    (h & 0xffff) as f32 / 32767.5 - 1.0
}

/// Sum of a few sinusoid octaves on the sphere, deterministic in `seed`.
fn displacement(p: Vec3, seed: u32) -> f32 {
    let mut d = 0.0;
    let mut freq = 3.0;
    let mut amp = 1.0;
    for o in 0..4 {
        let phase = Vec3::new(hash_noise(o, 1, seed), hash_noise(o, 2, seed), hash_noise(o, 3, seed)) * 3.0;
        d += amp * ((p.x * freq + phase.x).sin() * (p.y * freq + phase.y).sin() * (p.z * freq + phase.z).sin());
        freq *= 2.1;
        amp *= 0.5;
    }
    d
}

/// A unit sphere displaced radially by `amplitude` x smooth noise, centred at the
/// origin, with about `target_tris` triangles (at least 8) and smooth vertex normals.
pub fn blob(target_tris: usize, amplitude: f32, seed: u32) -> MeshData {
    // Triangles = 2 * slices * (stacks - 1) with slices = 2 * stacks.
    let stacks = (((target_tris.max(8)) as f64 / 4.0).sqrt().round() as usize).max(2);
    let slices = 2 * stacks;
    let mut positions = Vec::with_capacity((stacks + 1) * slices);
    for j in 0..=stacks {
        let theta = std::f32::consts::PI * j as f32 / stacks as f32;
        for i in 0..slices {
            let phi = 2.0 * std::f32::consts::PI * i as f32 / slices as f32;
            // At the poles every slice's vertex must be the same point, or the mesh
            // has a hole there: sin(pi) in f32 is -8.7e-8, not 0.
            let dir = if j == 0 {
                Vec3::Y
            } else if j == stacks {
                Vec3::NEG_Y
            } else {
                Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin())
            };
            let r = 1.0 + amplitude * displacement(dir, seed);
            positions.push(dir * r);
        }
    }
    let idx = |i: usize, j: usize| (j * slices + i % slices) as u32;
    let mut triangles = Vec::with_capacity(2 * slices * stacks);
    for j in 0..stacks {
        for i in 0..slices {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i, j + 1), idx(i + 1, j + 1));
            if j != 0 {
                triangles.push([a, b, c]);
            }
            if j != stacks - 1 {
                triangles.push([b, d, c]);
            }
        }
    }
    let normals = vertex_normals(&positions, &triangles);
    MeshData { positions, normals: Some(normals), triangles, ..Default::default() }
}

/// Area-weighted vertex normals; vertices of only degenerate triangles get +Y.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let f = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += f;
        }
    }
    n.into_iter().map(|v| v.try_normalize().unwrap_or(Vec3::Y)).collect()
}

/// A quad from four corners (counter-clockwise seen from its front), two triangles.
pub fn quad(corners: [Vec3; 4]) -> MeshData {
    MeshData { positions: corners.to_vec(), normals: None, triangles: vec![[0, 1, 2], [0, 2, 3]], ..Default::default() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blob_poles_are_single_points() {
        let m = blob(1000, 0.2, 3);
        let first = m.positions[0];
        let last = *m.positions.last().expect("vertices");
        let stacks = ((1000.0f64 / 4.0).sqrt().round()) as usize;
        assert!(m.positions[..2 * stacks].iter().all(|&p| p == first), "north pole");
        assert!(m.positions[m.positions.len() - 2 * stacks..].iter().all(|&p| p == last), "south pole");
    }

    #[test]
    fn blob_hits_target_and_is_closed_indices() {
        for n in [1000, 10_000, 100_000] {
            let m = blob(n, 0.1, 1);
            let got = m.triangles.len() as f64;
            assert!((got / n as f64 - 1.0).abs() < 0.05, "{n}: {got}");
            assert!(m.triangles.iter().flatten().all(|&i| (i as usize) < m.positions.len()));
        }
    }

    #[test]
    fn blob_is_deterministic() {
        assert_eq!(blob(500, 0.2, 7).positions, blob(500, 0.2, 7).positions);
    }
}
