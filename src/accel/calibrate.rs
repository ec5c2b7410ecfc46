//! The cache file of `arbor calibrate`: the cost model's constants
//! ([`super::auto::Costs`]) measured on one device (by `crate::bench::calibrate`;
//! docs/auto.md). The file is keyed by the
//! device's name and driver version and lives in the user's cache directory
//! (`ARBOR_CACHE_DIR`, else `$XDG_CACHE_HOME/arbor`, else `~/.cache/arbor`). A file
//! that cannot be read, is corrupt, or belongs to another device or driver is ignored
//! with a warning, never trusted. Nothing calibrates by itself.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::auto::{Costs, TreeCost};
use super::{AccelKind, BuildOn};
use crate::error::{Error, Result};
use crate::gpu::DeviceInfo;

/// The file format's version.
const FORMAT: u32 = 1;

#[derive(Debug, Serialize, Deserialize)]
struct File {
    format: u32,
    arbor: String,
    device: String,
    driver: String,
    brute_test_ns: f64,
    trees: Vec<Row>,
}

#[derive(Debug, Serialize, Deserialize)]
struct Row {
    kind: String,
    build: String,
    build_ns: f64,
    trace_ns: f64,
}

/// The cache directory: `ARBOR_CACHE_DIR` (non-empty), else `$XDG_CACHE_HOME/arbor`,
/// else `$HOME/.cache/arbor`; None without any of them.
pub fn cache_dir() -> Option<PathBuf> {
    let var = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty()).map(PathBuf::from);
    var("ARBOR_CACHE_DIR")
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("arbor")))
        .or_else(|| var("HOME").map(|d| d.join(".cache").join("arbor")))
}

/// The file for `device` in `dir`: its name and driver, letters and digits only.
pub fn cache_file(dir: &Path, device: &DeviceInfo) -> PathBuf {
    let key = format!("{} {}", device.name, device.driver);
    let mut name = String::from("calibration");
    for word in key.split(|c: char| !c.is_ascii_alphanumeric() && c != '.').filter(|w| !w.is_empty()) {
        name.push('-');
        name.push_str(word);
    }
    dir.join(format!("{name}.json"))
}

/// What the cache holds for a device.
#[derive(Debug)]
pub enum Cached {
    /// No file.
    Absent,
    /// The device's measured costs.
    Costs(Costs),
    /// A file that is not to be trusted, and why (a warning for the user).
    Ignored(String),
}

/// The cost model for `auto` on `device`: its calibration file in [`cache_dir`] if
/// there is a sound one, else the built-in constants; with the reason a foreign or
/// corrupt file was ignored (a warning for the user).
pub fn device_costs(device: &DeviceInfo) -> (Costs, Option<String>) {
    match cache_dir().map(|d| load(&d, device)) {
        Some(Cached::Costs(c)) => (c, None),
        Some(Cached::Ignored(why)) => (Costs::builtin(), Some(format!("calibration {why}"))),
        _ => (Costs::builtin(), None),
    }
}

/// The costs cached in `dir` for `device`.
pub fn load(dir: &Path, device: &DeviceInfo) -> Cached {
    let path = cache_file(dir, device);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Cached::Absent,
        Err(e) => return Cached::Ignored(format!("{}: cannot read it ({e}); ignored", path.display())),
    };
    let file: File = match serde_json::from_str(&text) {
        Ok(f) => f,
        Err(e) => return Cached::Ignored(format!("{}: corrupt ({e}); ignored, run `arbor calibrate`", path.display())),
    };
    if file.format != FORMAT {
        return Cached::Ignored(format!("{}: format {} is not {FORMAT}; ignored", path.display(), file.format));
    }
    if (file.device.as_str(), file.driver.as_str()) != (device.name.as_str(), device.driver.as_str()) {
        return Cached::Ignored(format!(
            "{}: measured on {} ({}), not on this device; ignored",
            path.display(),
            file.device,
            file.driver
        ));
    }
    let mut trees = Vec::new();
    for r in &file.trees {
        let (Ok(kind), Ok(build)) = (r.kind.parse::<AccelKind>(), r.build.parse::<BuildOn>()) else {
            return Cached::Ignored(format!("{}: unknown structure {} {}; ignored", path.display(), r.kind, r.build));
        };
        let sane = |x: f64| x.is_finite() && x > 0.0;
        if !sane(r.build_ns) || !sane(r.trace_ns) {
            return Cached::Ignored(format!("{}: {} has no positive costs; ignored", path.display(), r.kind));
        }
        trees.push(TreeCost { kind, build, build_ns: r.build_ns, trace_ns: r.trace_ns });
    }
    if trees.is_empty() || !(file.brute_test_ns.is_finite() && file.brute_test_ns > 0.0) {
        return Cached::Ignored(format!("{}: no costs in it; ignored", path.display()));
    }
    Cached::Costs(Costs {
        trees,
        brute_test_ns: file.brute_test_ns,
        source: format!("costs measured on this device by `arbor calibrate`, {}", path.display()),
    })
}

/// Creates `dir` if needed and checks that a file can be written there (before a
/// calibration spends its time).
pub fn check_writable(dir: &Path) -> Result<()> {
    let fail = |e: std::io::Error| Error::Failed(format!("{}: cannot write the cache there: {e}", dir.display()));
    std::fs::create_dir_all(dir).map_err(fail)?;
    let probe = dir.join(format!(".arbor-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(fail)?;
    std::fs::remove_file(&probe).map_err(fail)
}

/// Writes `costs` for `device` to its file in `dir` (whole or not at all); its path.
pub fn save(dir: &Path, device: &DeviceInfo, costs: &Costs) -> Result<PathBuf> {
    check_writable(dir)?;
    let file = File {
        format: FORMAT,
        arbor: env!("CARGO_PKG_VERSION").into(),
        device: device.name.clone(),
        driver: device.driver.clone(),
        brute_test_ns: costs.brute_test_ns,
        trees: costs
            .trees
            .iter()
            .map(|t| Row {
                kind: t.kind.name().into(),
                build: t.build.name().into(),
                build_ns: t.build_ns,
                trace_ns: t.trace_ns,
            })
            .collect(),
    };
    let path = cache_file(dir, device);
    let text = serde_json::to_string_pretty(&file).map_err(|e| Error::Failed(format!("calibration: {e}")))?;
    let tmp = path.with_extension("json.tmp");
    let fail = |e: std::io::Error| Error::Failed(format!("{}: cannot write the cache: {e}", path.display()));
    std::fs::write(&tmp, text).map_err(fail)?;
    std::fs::rename(&tmp, &path).map_err(fail)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn device(name: &str, driver: &str) -> DeviceInfo {
        DeviceInfo { name: name.into(), driver: driver.into(), ..DeviceInfo::default() }
    }

    fn costs() -> Costs {
        let mut c = Costs::builtin();
        c.trees.push(TreeCost { kind: AccelKind::Bvh4, build: BuildOn::Gpu, build_ns: 12.5, trace_ns: 99.0 });
        c
    }

    /// Saved costs come back for the same device and driver only; another driver's
    /// file is another file, and a file renamed onto this device's name is foreign.
    #[test]
    fn the_cache_is_keyed_by_device_and_driver() {
        let dir = tempfile::tempdir().expect("tempdir");
        let a = device("llvmpipe (LLVM 15.0.6, 256 bits)", "Mesa 22.3.6");
        let b = device("llvmpipe (LLVM 15.0.6, 256 bits)", "Mesa 25.0.1");
        assert!(matches!(load(dir.path(), &a), Cached::Absent));
        let path = save(dir.path(), &a, &costs()).expect("save");
        assert!(path.starts_with(dir.path()) && path.extension().is_some_and(|e| e == "json"));
        match load(dir.path(), &a) {
            Cached::Costs(c) => {
                assert_eq!(c.trees, costs().trees);
                assert_eq!(c.brute_test_ns, costs().brute_test_ns);
                assert!(c.source.contains("arbor calibrate"), "{}", c.source);
            }
            other => panic!("{other:?}"),
        }
        assert_ne!(cache_file(dir.path(), &a), cache_file(dir.path(), &b));
        assert!(matches!(load(dir.path(), &b), Cached::Absent));
        std::fs::copy(&path, cache_file(dir.path(), &b)).expect("copy");
        match load(dir.path(), &b) {
            Cached::Ignored(why) => assert!(why.contains("not on this device"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    /// A corrupt file, one with a cost that is not positive, one with an unknown
    /// structure: each ignored with its reason, never trusted.
    #[test]
    fn a_corrupt_cache_is_ignored_with_a_reason() {
        let dir = tempfile::tempdir().expect("tempdir");
        let d = device("gpu", "1.0");
        let path = save(dir.path(), &d, &costs()).expect("save");
        let good = std::fs::read_to_string(&path).expect("read");
        for (text, want) in [
            ("{ not json".to_string(), "corrupt"),
            (good.replace("\"trace_ns\": 99.0", "\"trace_ns\": -1.0"), "no positive costs"),
            (good.replacen("\"kind\": \"kdtree\"", "\"kind\": \"quadtree\"", 1), "unknown structure"),
            (good.replace("\"format\": 1", "\"format\": 9"), "format 9"),
        ] {
            std::fs::write(&path, &text).expect("write");
            match load(dir.path(), &d) {
                Cached::Ignored(why) => assert!(why.contains(want), "{want}: {why}"),
                other => panic!("{want}: {other:?}"),
            }
        }
    }

    /// A cache directory that cannot be created (it would sit under a regular file:
    /// tests run as root, so permissions would not stop them) fails, naming it.
    #[test]
    fn an_unwritable_cache_directory_is_an_error() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("plain");
        std::fs::write(&file, "x").expect("write");
        let under = file.join("cache");
        let err = save(&under, &device("gpu", "1.0"), &costs()).expect_err("unwritable").to_string();
        assert!(err.contains(&under.display().to_string()), "{err}");
        assert!(check_writable(&under).is_err());
    }
}
