//! `arbor compare`: the figures of identical and known-different images in every input
//! format, the --diff image, and one-line errors with exit status 2 that write nothing.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use arbor::render::output::{encode_image, encode_pfm, Format};

fn arbor(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).output().expect("run arbor")
}

fn json(args: &[&str]) -> serde_json::Value {
    let out = arbor(args);
    assert!(out.status.success(), "arbor {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Writes `pixels` (row 0 at the top) as `name` in `dir`, in the format of its extension.
fn write(dir: &Path, name: &str, w: u32, h: u32, pixels: &[[f32; 3]]) -> PathBuf {
    let path = dir.join(name);
    let bytes = match path.extension().and_then(|e| e.to_str()) {
        Some("pfm") => encode_pfm(w, h, 3, &pixels.iter().flatten().copied().collect::<Vec<_>>()),
        Some("exr") => encode_image(Format::Exr, w, h, pixels).expect("EXR"),
        Some("png") => encode_image(Format::Png, w, h, pixels).expect("PNG"),
        Some("hdr") => {
            let mut out = Vec::new();
            let px: Vec<image::Rgb<f32>> = pixels.iter().map(|&p| image::Rgb(p)).collect();
            image::codecs::hdr::HdrEncoder::new(&mut out).encode(&px, w as usize, h as usize).expect("HDR");
            out
        }
        other => panic!("no writer for {other:?}"),
    };
    std::fs::write(&path, bytes).expect("write image");
    path
}

const A: [[f32; 3]; 2] = [[0.5, 0.5, 0.5], [1.5, 0.0, 0.0]];
const B: [[f32; 3]; 2] = [[0.25, 0.5, 0.5], [1.0, 0.0, 0.0]];

#[test]
fn identical_images_have_zero_error_and_infinite_psnr() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = write(dir.path(), "a.pfm", 2, 1, &A);
    let out = arbor(&["compare", &s(&a), &s(&a)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(text, "mse      0\nrel_mse  0\npsnr     inf dB\nmax_abs  0\n");
    let v = json(&["compare", &s(&a), &s(&a), "--json"]);
    assert_eq!((v["mse"].as_f64(), v["psnr"].as_str()), (Some(0.0), Some("inf")), "{v}");
    // The same pixels in every linear format compare equal to the PFM.
    for name in ["a.exr", "a.hdr"] {
        let other = write(dir.path(), name, 2, 1, &A);
        let v = json(&["compare", &s(&other), &s(&a), "--json"]);
        assert_eq!(v["max_abs"].as_f64(), Some(0.0), "{name}: {v}");
    }
}

#[test]
fn known_difference_gives_the_exact_figures_and_a_diff_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = write(dir.path(), "a.exr", 2, 1, &A);
    let b = write(dir.path(), "b.pfm", 2, 1, &B);
    let diff = dir.path().join("d.png");
    let v = json(&["compare", &s(&a), &s(&b), "--json", "--diff", &s(&diff)]);
    let close = |key: &str, want: f64| {
        let got = v[key].as_f64().unwrap_or(f64::NAN);
        assert!((got - want).abs() <= 1e-12 * want.abs(), "{key}: {got} vs {want}");
    };
    close("mse", 0.3125 / 6.0);
    close("rel_mse", (0.0625 / 0.0725 + 0.25 / 1.01) / 6.0);
    close("psnr", 10.0 * 96f64.log10()); // clamped to [0, 1]: only 0.5 vs 0.25 differs
    close("max_abs", 0.5);
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(2), Some(1)));
    let img = image::open(&diff).expect("diff PNG").into_rgb8();
    assert_eq!(img.dimensions(), (2, 1));
    // Relative errors 0.287 (between yellow and red) and 0.083 (just under yellow).
    assert_eq!(img.get_pixel(0, 0).0, arbor::render::output::compare::error_color((0.0625 / 0.0725) / 3.0));
    assert_eq!(img.get_pixel(1, 0).0, arbor::render::output::compare::error_color((0.25 / 1.01) / 3.0));
}

#[test]
fn png_is_srgb_decoded_to_linear() {
    let dir = tempfile::tempdir().expect("tempdir");
    let px = [[0.5, 0.2, 0.0], [1.0, 0.01, 0.8]];
    let png = write(dir.path(), "a.png", 2, 1, &px);
    let pfm = write(dir.path(), "a.pfm", 2, 1, &px);
    let v = json(&["compare", &s(&png), &s(&pfm), "--json"]);
    let max = v["max_abs"].as_f64().unwrap_or(f64::NAN);
    assert!(max < 4e-3, "8-bit sRGB round trip error {max}");
}

/// The stderr of a failed compare: exit status 1 (2 for a command-line mistake, `code`),
/// one line naming `file`, no --diff file.
fn fails_naming(args: &[&str], file: &Path, diff: &Path) -> String {
    fails_with(1, args, file, diff)
}

fn fails_with(code: i32, args: &[&str], file: &Path, diff: &Path) -> String {
    let out = arbor(args);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(code), "arbor {args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("arbor: error: ") && err.contains(&s(file)), "{err} does not name {}", file.display());
    assert!(out.stdout.is_empty());
    assert!(!diff.exists(), "{} was written", diff.display());
    let left: Vec<_> = std::fs::read_dir(diff.parent().expect("dir"))
        .expect("list")
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
    err
}

#[test]
fn bad_inputs_exit_1_with_one_line_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let diff = d.join("d.png");
    let diff_s = s(&diff);
    let a = write(d, "a.exr", 2, 1, &A);
    let small = write(d, "small.pfm", 1, 1, &A[..1]);
    let e = fails_naming(&["compare", &s(&small), &s(&a), "--diff", &diff_s], &small, &diff);
    assert!(e.contains("is 1x1 but the reference") && e.contains("2x1"), "{e}");
    let missing = d.join("missing.exr");
    fails_naming(&["compare", &s(&a), &s(&missing), "--diff", &diff_s], &missing, &diff);
    let garbage = d.join("garbage.exr");
    std::fs::write(&garbage, b"this is not an image").expect("write");
    fails_naming(&["compare", &s(&garbage), &s(&a), "--diff", &diff_s], &garbage, &diff);
    let bad_pfm = d.join("bad.pfm");
    std::fs::write(&bad_pfm, b"PF\n2 1\n-1\n\0\0").expect("write");
    let e = fails_naming(&["compare", &s(&a), &s(&bad_pfm), "--diff", &diff_s], &bad_pfm, &diff);
    assert!(e.contains("bad PFM file"), "{e}");
    let unknown = d.join("a.txt");
    std::fs::write(&unknown, b"1 2 3").expect("write");
    let e = fails_naming(&["compare", &s(&unknown), &s(&a), "--diff", &diff_s], &unknown, &diff);
    assert!(e.contains("unknown image format"), "{e}");
    let jpg_diff = d.join("d.jpg");
    fails_with(2, &["compare", &s(&a), &s(&a), "--diff", &s(&jpg_diff)], &jpg_diff, &jpg_diff);
    let nan = write(d, "nan.pfm", 2, 1, &[[0.0, f32::NAN, 0.0], [0.0; 3]]);
    let e = fails_naming(&["compare", &s(&nan), &s(&a), "--diff", &diff_s], &nan, &diff);
    assert!(e.contains("pixel (0, 0) is not finite"), "{e}");
}

/// An EXR that arbor rendered compares equal to itself.
#[test]
fn rendered_exr_compares_equal_to_itself() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let exr = s(&dir.path().join("x.exr"));
    let out = arbor(&["render", "builtin:spheres", "--size", "32x20", "-o", &exr, "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v = json(&["compare", &exr, &exr, "--json"]);
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(32), Some(20)), "{v}");
    assert_eq!((v["mse"].as_f64(), v["rel_mse"].as_f64(), v["psnr"].as_str()), (Some(0.0), Some(0.0), Some("inf")));
}
