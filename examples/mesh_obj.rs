//! Writes the triangles of any scene arbor loads (a mesh file, a scene TOML,
//! `builtin:blob:N`, ...) as a Wavefront OBJ: positions and faces only, instances
//! flattened. For peers that read mesh files (`scripts/peers/embree_rays.cpp`), so that
//! they and `arbor bench --scene FILE.obj` trace the same triangles.
//!
//! ```text
//! cargo run --example mesh_obj -- builtin:blob:100000 blob100k.obj
//! ```

use std::io::Write;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 || args[0].starts_with('-') {
        eprintln!("usage: mesh_obj SCENE OUT.obj");
        std::process::exit(2);
    }
    let scene = match arbor::scene::Scene::load(&args[0]).and_then(|s| s.flattened()) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("mesh_obj: {e}");
            std::process::exit(1);
        }
    };
    let write = || -> std::io::Result<()> {
        let mut out = std::io::BufWriter::new(std::fs::File::create(&args[1])?);
        writeln!(out, "# {} ({} triangles), written by arbor's mesh_obj example", scene.name, scene.triangles.len())?;
        for p in &scene.positions {
            writeln!(out, "v {} {} {}", p.x, p.y, p.z)?;
        }
        for t in &scene.triangles {
            writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        out.flush()
    };
    if let Err(e) = write() {
        eprintln!("mesh_obj: {}: {e}", args[1]);
        std::process::exit(1);
    }
    eprintln!("wrote {} ({} triangles)", args[1], scene.triangles.len());
}
