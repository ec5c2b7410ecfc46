//! The Slurm example for real: a single-node cluster on this machine
//! (examples/slurm/local-cluster.sh: munged, slurmctld, slurmd), the job array and the
//! dependent merge job of examples/slurm/submit.sh, and the merged image against a
//! single-process render. In CI (ARBOR_REQUIRE_GPU=1) it never skips: a cluster that
//! cannot start fails the test with the daemons' logs.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/slurm").join(name)
}

/// Stops the cluster's daemons when dropped, whatever happened.
struct Cluster {
    dir: PathBuf,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash").arg(script("local-cluster.sh")).arg("stop").arg(&self.dir).status();
    }
}

fn logs(dir: &Path) -> String {
    let mut out = String::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = entry.path();
        if p.extension().is_some_and(|e| e == "log") {
            let text = std::fs::read_to_string(&p).unwrap_or_default();
            let tail: Vec<&str> = text.lines().rev().take(30).collect();
            out += &format!("---- {}\n{}\n", p.display(), tail.into_iter().rev().collect::<Vec<_>>().join("\n"));
        }
    }
    out
}

#[test]
fn slurm_job_array_and_merge_equal_a_single_render() {
    if !common::has_gpu() {
        return;
    }
    let have_slurm = Command::new("sh").args(["-c", "command -v slurmctld && command -v munged"]).output();
    let have_slurm = have_slurm.is_ok_and(|o| o.status.success());
    let root = Command::new("id").arg("-u").output().is_ok_and(|o| o.stdout.starts_with(b"0\n"));
    if !(have_slurm && root) {
        assert!(
            !common::gpu_required(),
            "the Slurm test needs slurm-wlm and munge (scripts/setup.sh) and root; found slurm: {have_slurm}, root: {root}"
        );
        eprintln!("skipped: needs slurm-wlm, munge and root");
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let cluster_dir = dir.path().join("cluster");
    let port = 20_000 + std::process::id() % 20_000;
    let start = Command::new("bash")
        .arg(script("local-cluster.sh"))
        .arg("start")
        .arg(&cluster_dir)
        .env("PORT", port.to_string())
        .output()
        .expect("run local-cluster.sh");
    let _cluster = Cluster { dir: cluster_dir.clone() };
    assert!(
        start.status.success(),
        "the cluster did not start:\n{}\n{}",
        String::from_utf8_lossy(&start.stderr),
        logs(&cluster_dir)
    );
    let conf = cluster_dir.join("slurm.conf");
    let arbor = env!("CARGO_BIN_EXE_arbor");
    let image = dir.path().join("frame.exr");
    let mut child = Command::new("bash")
        .arg(script("submit.sh"))
        .args(["builtin:cornell", "3"])
        .arg(&image)
        .args(["--size", "64x48", "--spp", "4"])
        .current_dir(dir.path())
        .env("SLURM_CONF", &conf)
        .env("ARBOR", arbor)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run submit.sh");
    let deadline = Instant::now() + Duration::from_secs(300);
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("the jobs did not finish in 300 s:\n{}{}", logs(&cluster_dir), logs(dir.path()));
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    let out = child.wait_with_output().expect("output");
    assert!(
        status.success(),
        "submit.sh failed: {}\n{}{}",
        String::from_utf8_lossy(&out.stderr),
        logs(&cluster_dir),
        logs(dir.path())
    );
    // Three array tasks wrote three tiles; the merge job assembled them.
    for i in 0..3 {
        let part = dir.path().join(format!("frame.exr.parts/part-{i}.exr"));
        let (info, _) = arbor::render::output::part::read(&part).expect("a part");
        assert_eq!(info.shard, format!("{i}/3 tiles"));
    }
    let single = dir.path().join("single.exr");
    let status = Command::new(arbor)
        .args(["render", "builtin:cornell", "--size", "64x48", "--spp", "4", "-q", "-o"])
        .arg(&single)
        .status()
        .expect("render");
    assert!(status.success());
    let (_, merged) = arbor::render::output::part::read(&image).expect("the merged image");
    let (_, whole) = arbor::render::output::part::read(&single).expect("the single render");
    assert_eq!(merged.sum, whole.sum, "the cluster's image is the single render's, bit for bit");
    assert_eq!(merged.radiance, whole.radiance);
    assert_eq!(merged.prim, whole.prim);
    assert_eq!(merged.samples, whole.samples);
}
