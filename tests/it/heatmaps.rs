//! The counting AOVs as pictures (`render --aov cost=heat.png`, `nodes`, `tests`): the
//! PNG holds the counts of the PFMs of the same render, colour for colour at an integer
//! zoom, a colour bar from viridis(1) at the top to viridis(0) at the bottom, text above
//! and below; `--aov-scale log` changes the colours; the errors for a .png of another
//! AOV, a stray `--aov-scale`, and the counting AOVs with the driver's structure.

use crate::common;

use std::path::Path;
use std::process::{Command, Output};

use arbor::render::output::heatmap::{colour, viridis, Scale, MIN_MAP_SIDE};
use arbor::render::output::read_pfm;
use image::RgbImage;

/// arbor with `ARBOR_FONT` unset: the pictures' text is in the built-in font.
fn arbor(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arbor")).args(args).env_remove("ARBOR_FONT").output().expect("run arbor")
}

fn ok(args: &[&str]) {
    let out = arbor(args);
    assert!(out.status.success(), "arbor {args:?} failed:\n{}", String::from_utf8_lossy(&out.stderr));
}

/// Fails with every one of `needles` in stderr (case-insensitive) and writes nothing in `dir`.
fn fails(dir: &Path, args: &[&str], needles: &[&str]) {
    let out = arbor(args);
    let err = String::from_utf8_lossy(&out.stderr).to_lowercase();
    assert!(!out.status.success(), "arbor {args:?} succeeded");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(&n.to_lowercase()), "arbor {args:?}: stderr lacks {n:?}: {err}");
    }
    let left: Vec<_> = std::fs::read_dir(dir).expect("list").collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
}

fn px(img: &RgbImage, x: u32, y: u32) -> [u8; 3] {
    img.get_pixel(x, y).0
}

/// The top-left corner of the map of `values` (`w` x `h`, zoomed `k` times) in `img`,
/// every pixel in the colour of its value on `scale`, from the values' minimum to their
/// maximum; None when there is no such map.
fn find_map(img: &RgbImage, values: &[f32], w: u32, h: u32, k: u32, scale: Scale) -> Option<(u32, u32)> {
    let lo = values.iter().fold(f64::INFINITY, |a, &v| a.min(f64::from(v)));
    let hi = values.iter().fold(f64::NEG_INFINITY, |a, &v| a.max(f64::from(v)));
    let want: Vec<[u8; 3]> = values.iter().map(|&v| colour(f64::from(v), lo, hi, scale)).collect();
    let fits = |ox: u32, oy: u32| {
        (0..h).all(|y| {
            (0..w).all(|x| {
                let c = want[(y * w + x) as usize];
                let (x0, y0) = (ox + x * k, oy + y * k);
                px(img, x0, y0) == c && px(img, x0 + k - 1, y0 + k - 1) == c
            })
        })
    };
    let (xs, ys) = (img.width().checked_sub(w * k)?, img.height().checked_sub(h * k)?);
    (0..=ys).flat_map(|oy| (0..=xs).map(move |ox| (ox, oy))).find(|&(ox, oy)| fits(ox, oy))
}

/// The colour bar: a column right of `from_x` that runs down from viridis(1) to
/// viridis(0) over at least `min_len` rows, its green never rising. Returns (x, top, bottom).
fn find_bar(img: &RgbImage, from_x: u32, min_len: u32) -> Option<(u32, u32, u32)> {
    let (top, bottom) = (viridis(1.0), viridis(0.0));
    for x in from_x..img.width() {
        for y in 0..img.height() {
            if px(img, x, y) != top {
                continue;
            }
            let mut y2 = y + 1;
            while y2 < img.height() && px(img, x, y2)[1] <= px(img, x, y2 - 1)[1] && px(img, x, y2 - 1) != bottom {
                y2 += 1;
            }
            if px(img, x, y2 - 1) == bottom && y2 - y >= min_len {
                return Some((x, y, y2 - 1));
            }
        }
    }
    None
}

/// Some dark (text) pixel in rows `y0..y1`.
fn has_text(img: &RgbImage, y0: u32, y1: u32) -> bool {
    (y0..y1.min(img.height())).any(|y| (0..img.width()).any(|x| px(img, x, y).iter().all(|&c| c < 90)))
}

/// Checks a heatmap PNG of `values` against everything it must show; returns the map's
/// corner.
fn check_picture(path: &Path, values: &[f32], w: u32, h: u32, scale: Scale) -> (u32, u32) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let k = MIN_MAP_SIDE.div_ceil(w.max(h));
    let (mw, mh) = (w * k, h * k);
    // The map, the bar, a line of text above and two below: no more than a margin around.
    assert!(img.width() > mw + 40 && img.width() <= (mw + 260).max(460), "{}: width {}", path.display(), img.width());
    assert!(img.height() > mh + 60 && img.height() <= mh + 200, "{}: height {}", path.display(), img.height());
    let (ox, oy) = find_map(&img, values, w, h, k, scale)
        .unwrap_or_else(|| panic!("{}: no {w}x{h} map zoomed {k}x in the {scale:?} colours", path.display()));
    let mut colours: Vec<[u8; 3]> =
        (0..mh).flat_map(|y| (0..mw).map(move |x| (x, y))).map(|(x, y)| px(&img, ox + x, oy + y)).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() >= 5, "{}: the map has only {} colours", path.display(), colours.len());
    let (_, top, bottom) =
        find_bar(&img, ox + mw, 150).unwrap_or_else(|| panic!("{}: no colour bar right of the map", path.display()));
    assert!(top >= oy && bottom >= oy + mh - 1, "{}: the bar ({top}..{bottom}) is beside the map", path.display());
    assert!(has_text(&img, 0, oy), "{}: no title above the map", path.display());
    assert!(has_text(&img, oy + mh.max(bottom - oy) + 1, img.height()), "{}: no text under the map", path.display());
    (ox, oy)
}

#[test]
fn heatmap_pngs_show_the_counts_of_the_pfms() {
    if !common::has_gpu() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |n: &str| dir.path().join(n).display().to_string();
    let (w, h) = (64u32, 48u32);
    let base = ["render", "builtin:default", "--accel", "kdtree", "--integrator", "whitted", "--size", "64x48"];
    let lin = format!("nodes={},tests={},cost={}", p("n.pfm"), p("t.pfm"), p("cost.png"));
    ok(&[&base[..], &["-o", &p("a.png"), "--aov", &lin, "--quiet"]].concat());
    let log = format!("cost={},nodes={}", p("cost_log.png"), p("nodes_log.png"));
    ok(&[&base[..], &["-o", &p("b.png"), "--aov", &log, "--aov-scale", "log", "--quiet"]].concat());
    let tests = format!("tests={}", p("tests.png"));
    ok(&[&base[..], &["-o", &p("c.png"), "--aov", &tests, "--quiet"]].concat());

    let (pw, ph, c, nodes) = read_pfm(Path::new(&p("n.pfm"))).expect("nodes PFM");
    assert_eq!((pw, ph, c), (w, h, 1));
    let (_, _, _, tests) = read_pfm(Path::new(&p("t.pfm"))).expect("tests PFM");
    let cost: Vec<f32> = nodes.iter().zip(&tests).map(|(n, t)| n + t).collect();
    assert!(nodes.iter().any(|&n| n > 0.0) && tests.iter().any(|&t| t > 0.0));

    check_picture(Path::new(&p("cost.png")), &cost, w, h, Scale::Linear);
    check_picture(Path::new(&p("tests.png")), &tests, w, h, Scale::Linear);
    check_picture(Path::new(&p("nodes_log.png")), &nodes, w, h, Scale::Log);
    let (ox, oy) = check_picture(Path::new(&p("cost_log.png")), &cost, w, h, Scale::Log);
    // The log picture is not the linear one: its map is not in the linear colours.
    let log_img = image::open(p("cost_log.png")).expect("png").to_rgb8();
    assert!(find_map(&log_img, &cost, w, h, 4, Scale::Linear).is_none(), "log and linear maps are the same");
    let lin_img = image::open(p("cost.png")).expect("png").to_rgb8();
    let differ = (0..h * 4)
        .flat_map(|y| (0..w * 4).map(move |x| (x, y)))
        .filter(|&(x, y)| px(&lin_img, ox + x, oy + y) != px(&log_img, ox + x, oy + y));
    assert!(differ.count() > (w * h) as usize, "log and linear pictures hardly differ");
}

#[test]
fn png_is_for_the_counting_aovs_only() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path().join("out");
    std::fs::create_dir(&d).expect("mkdir");
    let p = |n: &str| d.join(n).display().to_string();
    let render = |aov: String, extra: &[&str], needles: &[&str]| {
        let out = p("a.png");
        let args: Vec<&str> =
            [&["render", "builtin:default", "--size", "8x8", "-o", &out, "--aov", &aov][..], extra].concat();
        fails(&d, &args, needles);
    };
    for name in ["depth", "normal", "prim", "albedo", "variance", "samples"] {
        let path = p(&format!("{name}.png"));
        render(format!("{name}={path}"), &[], &[&path, "only cost, nodes, tests", ".pfm or .exr"]);
    }
    render(format!("cost={}", p("c.jpg")), &[], &["c.jpg", ".pfm or .exr", ".png"]);
    render(format!("nodes={}", p("n.pfm")), &["--aov-scale", "log"], &["--aov-scale", "no --aov is one"]);
    let out = arbor(&["render", "builtin:default", "--aov-scale", "sqrt", "--aov", "cost=x.png"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("sqrt"));
}

/// The driver's structure does not count what it visits: no cost, nodes or tests, in
/// any format (refused before a device is opened).
#[test]
fn rayquery_refuses_the_counting_aovs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path().join("out");
    std::fs::create_dir(&d).expect("mkdir");
    let out = d.join("a.png").display().to_string();
    for (name, file) in
        [("cost", "c.pfm"), ("nodes", "n.pfm"), ("tests", "t.exr"), ("nodes", "n.png"), ("cost", "c.png")]
    {
        let aov = format!("{name}={}", d.join(file).display());
        fails(
            &d,
            &["render", "builtin:default", "--accel", "rayquery", "--size", "8x8", "-o", &out, "--aov", &aov],
            &[&format!("--aov {name}"), "driver's structure", "does not say how many nodes"],
        );
    }
}
