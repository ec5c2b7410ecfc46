//! The names a trace kernel variant is made of: the kernel family that traverses a
//! structure ([`KernelFamily`]) and the geometry the variant handles ([`Geometry`]).
//! build.rs compiles `trace_<family>_<geometry>` and `rays_<family>_<geometry>` for
//! every `shaders/accel/<family>.glsl` and geometry, and `trace_inst_<family>_<geometry>`
//! (geometry with triangles) for every family but brute force; [`KernelFamily::name`]
//! and [`Geometry::name`] give exactly those parts.

use std::fmt;

/// The kernel family that traverses a structure: `shaders/accel/<name>.glsl`, over a
/// flat scene or (`Inst*`) over the two-level structure of an instanced scene
/// ([`super::instance`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum KernelFamily {
    /// Brute force (`none`); no buffers of its own, no instance level.
    None,
    /// kd-trees (`kdtree`).
    Kdtree,
    /// Binary BVHs (`bvh`), the only family with packet traversal.
    Bvh,
    /// 4-wide BVHs (`bvh4`).
    Bvh4,
    /// 8-wide BVHs (`bvh8`).
    Bvh8,
    /// Compressed 8-wide BVHs (`cwbvh`).
    Cwbvh,
    /// Uniform grids (`grid`).
    Grid,
    /// Octrees (`octree`).
    Octree,
    /// The driver's structure, traced with ray queries (`rayquery`); no buffers.
    RayQuery,
    /// Two-level `bvh` (`inst_bvh`).
    InstBvh,
    /// Two-level `bvh4` (`inst_bvh4`).
    InstBvh4,
    /// Two-level `bvh8` (`inst_bvh8`).
    InstBvh8,
    /// Two-level `cwbvh` (`inst_cwbvh`).
    InstCwbvh,
    /// Two-level `kdtree` (`inst_kdtree`).
    InstKdtree,
    /// Two-level `grid` (`inst_grid`).
    InstGrid,
    /// Two-level `octree` (`inst_octree`).
    InstOctree,
    /// The driver's structure over an instanced scene (`inst_rayquery`): it reads the
    /// two-level records from the node buffer.
    InstRayQuery,
}

impl KernelFamily {
    /// Every family, flat ones first.
    pub const EVERY: [KernelFamily; 17] = [
        KernelFamily::None,
        KernelFamily::Kdtree,
        KernelFamily::Bvh,
        KernelFamily::Bvh4,
        KernelFamily::Bvh8,
        KernelFamily::Cwbvh,
        KernelFamily::Grid,
        KernelFamily::Octree,
        KernelFamily::RayQuery,
        KernelFamily::InstBvh,
        KernelFamily::InstBvh4,
        KernelFamily::InstBvh8,
        KernelFamily::InstCwbvh,
        KernelFamily::InstKdtree,
        KernelFamily::InstGrid,
        KernelFamily::InstOctree,
        KernelFamily::InstRayQuery,
    ];

    /// The family's part of a kernel name (`trace_<name>_<geometry>`).
    pub fn name(self) -> &'static str {
        match self {
            KernelFamily::None => "none",
            KernelFamily::Kdtree => "kdtree",
            KernelFamily::Bvh => "bvh",
            KernelFamily::Bvh4 => "bvh4",
            KernelFamily::Bvh8 => "bvh8",
            KernelFamily::Cwbvh => "cwbvh",
            KernelFamily::Grid => "grid",
            KernelFamily::Octree => "octree",
            KernelFamily::RayQuery => "rayquery",
            KernelFamily::InstBvh => "inst_bvh",
            KernelFamily::InstBvh4 => "inst_bvh4",
            KernelFamily::InstBvh8 => "inst_bvh8",
            KernelFamily::InstCwbvh => "inst_cwbvh",
            KernelFamily::InstKdtree => "inst_kdtree",
            KernelFamily::InstGrid => "inst_grid",
            KernelFamily::InstOctree => "inst_octree",
            KernelFamily::InstRayQuery => "inst_rayquery",
        }
    }

    /// The family that traverses arbor's two-level structure ([`super::instance`])
    /// with this family's structures as the bottom level; `None` for brute force, which
    /// has no instance level, for the driver's structure (its two-level form,
    /// `InstRayQuery`, is [`super::rayquery`]'s own), and for a two-level family.
    pub fn instanced(self) -> Option<KernelFamily> {
        Some(match self {
            KernelFamily::Kdtree => KernelFamily::InstKdtree,
            KernelFamily::Bvh => KernelFamily::InstBvh,
            KernelFamily::Bvh4 => KernelFamily::InstBvh4,
            KernelFamily::Bvh8 => KernelFamily::InstBvh8,
            KernelFamily::Cwbvh => KernelFamily::InstCwbvh,
            KernelFamily::Grid => KernelFamily::InstGrid,
            KernelFamily::Octree => KernelFamily::InstOctree,
            _ => return None,
        })
    }

    /// Whether the kernel reads node and index buffers (`accel_nodes`, `accel_indices`):
    /// every family but brute force and the driver's structure over a flat scene (over
    /// an instanced scene it reads the two-level records from the node buffer).
    pub fn has_buffers(self) -> bool {
        !matches!(self, KernelFamily::None | KernelFamily::RayQuery)
    }

    /// Whether the kernel traces the driver's structure with ray queries (`tlas`).
    pub fn uses_ray_queries(self) -> bool {
        matches!(self, KernelFamily::RayQuery | KernelFamily::InstRayQuery)
    }

    /// Whether the kernel has packet traversal (`SPEC_PACKET`): flat binary BVHs only.
    pub fn has_packet_traversal(self) -> bool {
        self == KernelFamily::Bvh
    }

    /// Whether the family traverses an instanced scene's two levels.
    pub fn is_instanced(self) -> bool {
        matches!(
            self,
            KernelFamily::InstBvh
                | KernelFamily::InstBvh4
                | KernelFamily::InstBvh8
                | KernelFamily::InstCwbvh
                | KernelFamily::InstKdtree
                | KernelFamily::InstGrid
                | KernelFamily::InstOctree
                | KernelFamily::InstRayQuery
        )
    }
}

impl fmt::Display for KernelFamily {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The primitives a kernel variant handles: it declares (and binds) only their buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Geometry {
    /// Triangles only (`tris`).
    Tris,
    /// Spheres only (`spheres`).
    Spheres,
    /// Triangles and spheres (`all`).
    All,
}

impl Geometry {
    /// Every geometry, in build.rs's order.
    pub const ALL: [Geometry; 3] = [Geometry::Tris, Geometry::Spheres, Geometry::All];

    /// The variant for primitives of these kinds: only what there is, and `All` for
    /// both or neither.
    pub fn of(triangles: bool, spheres: bool) -> Geometry {
        match (triangles, spheres) {
            (true, false) => Geometry::Tris,
            (false, true) => Geometry::Spheres,
            _ => Geometry::All,
        }
    }

    /// The geometry's part of a kernel name (`trace_<family>_<name>`).
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Tris => "tris",
            Geometry::Spheres => "spheres",
            Geometry::All => "all",
        }
    }

    /// Whether the variant handles triangles (declares the vertex and triangle buffers).
    pub fn has_triangles(self) -> bool {
        self != Geometry::Spheres
    }

    /// Whether the variant handles spheres (declares the sphere buffer).
    pub fn has_spheres(self) -> bool {
        self != Geometry::Tris
    }
}

impl fmt::Display for Geometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every family and geometry names a kernel build.rs compiled (two-level families
    /// with triangles only; ray batches for flat families), and back.
    #[test]
    fn every_family_and_geometry_names_a_compiled_kernel() {
        if option_env!("ARBOR_DEV_KERNELS").is_some_and(|v| !v.is_empty()) {
            return; // a development build compiles only the kernels it names
        }
        for family in KernelFamily::EVERY {
            for geometry in Geometry::ALL {
                let compiled = !family.is_instanced() || geometry.has_triangles();
                for (entry, _) in crate::gpu::bindings::TRACE_ENTRIES {
                    let trace = format!("trace_{family}_{geometry}.{entry}");
                    assert_eq!(crate::gpu::spirv::get(&trace).is_some(), compiled, "{trace}");
                }
                assert!(crate::gpu::spirv::get(&format!("trace_{family}_{geometry}")).is_none());
                let rays = format!("rays_{family}_{geometry}");
                assert_eq!(crate::gpu::spirv::get(&rays).is_some(), !family.is_instanced(), "{rays}");
                // Brute force once more per unrolled loop; no other family.
                for unroll in crate::gpu::bindings::BRUTE_UNROLL_FACTORS.into_iter().filter(|&u| u > 1) {
                    for prefix in ["trace", "rays"] {
                        let dot_path = if prefix == "trace" { ".path" } else { "" };
                        let name = format!("{prefix}_{family}_{geometry}_x{unroll}{dot_path}");
                        assert_eq!(crate::gpu::spirv::get(&name).is_some(), family == KernelFamily::None, "{name}");
                    }
                }
            }
            assert_eq!(family.is_instanced(), family.name().starts_with("inst_"), "{family}");
            if let Some(inst) = family.instanced() {
                assert_eq!(inst.name(), format!("inst_{family}"));
                assert!(inst.is_instanced() && inst.instanced().is_none());
            }
        }
        assert_eq!(KernelFamily::None.instanced(), None);
        assert_eq!(KernelFamily::RayQuery.instanced(), None);
        assert_eq!(Geometry::ALL.map(Geometry::name), ["tris", "spheres", "all"]);
    }
}
