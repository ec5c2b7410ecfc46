//! Importance sampling of an environment map: a piecewise-constant 2D distribution over
//! [0,1)^2 (one cell per texel), its inversion on the CPU, and the flat array the GPU
//! kernel samples with the same arithmetic. After pbrt's `Distribution1D` /
//! `Distribution2D` (Pharr, Jakob & Humphreys, *Physically Based Rendering*, 3rd ed.,
//! 13.6.5 and 14.2.4), written for this layout.
//!
//! # The function
//!
//! For an environment of W x H texels, cell (x, y) has the weight
//! `f(x, y) = luminance(texel(x, y)) * sin(theta_y)`, `theta_y = pi * (y + 0.5) / H`
//! (row centre), `luminance = 0.2126 r + 0.7152 g + 0.0722 b`; `intensity` and
//! `rotation` do not change it. Negative or non-finite weights count as 0. A row whose
//! weights are all 0 gets a uniform conditional CDF (and marginal probability 0); a map
//! that is all 0 is sampled uniformly.
//!
//! # Sampling and densities
//!
//! `sample(u1, u2)`: `u2` picks the row from the marginal CDF, `u1` the column from that
//! row's conditional CDF; inside the chosen cell the position is linear in `u`
//! (continuous). The density is with respect to area on [0,1)^2 and is constant per cell:
//!
//! ```text
//! pdf_uv(x, y) = (cdf_y[x+1] - cdf_y[x]) * W * (marg[y+1] - marg[y]) * H
//! ```
//!
//! computed from the f32 CDFs only, so the CPU and the GPU agree bit for bit. The density
//! with respect to solid angle is ([`pdf_solid_angle`])
//! `pdf_omega = pdf_uv / (2 pi^2 sin theta)`, theta = pi v (0 where sin theta = 0).
//!
//! # The flat array (`gpu_rows`)
//!
//! `N = (H + 1) + 1 + H * (W + 1)` f32 values, 4 bytes each, little-endian as uploaded:
//!
//! ```text
//! float index            byte offset               content
//! 0 ..= H                0 .. 4(H+1)               marginal CDF marg[0..=H]: marg[0] = 0, marg[H] = 1.0 exactly
//! H + 1                  4(H+1)                    integral of f over [0,1)^2 = sum f / (W H) (0 for an all-0 map)
//! R(y) + x, x in 0..=W   4 R(y) + 4x               row y's conditional CDF cdf_y[x]: cdf_y[0] = 0, cdf_y[W] = 1.0
//!   with R(y) = H + 2 + y (W + 1), y in 0..H
//! ```
//!
//! Example, W = 2, H = 1, f = [1, 3]: `[0, 1, 2, 0, 0.25, 1]`.
//!
//! Both CDFs are non-decreasing. Sampling ([`sample_flat`], which the GLSL mirrors line
//! by line): `u` is clamped to `[0, ONE_MINUS_EPSILON]`; [`find_interval`] returns the
//! largest `i < n` with `cdf[i] <= u` by a binary search of at most
//! `floor(log2(n)) + 1` iterations; the chosen cell then has `cdf[i+1] > u`, so a
//! non-zero probability. The position is `(i + (u - cdf[i]) / (cdf[i+1] - cdf[i])) / n`,
//! clamped to `ONE_MINUS_EPSILON`.
//!
//! # Directions
//!
//! [`uv_to_dir`]: `phi = 2 pi u - rotation_radians`, `theta = pi v`,
//! `dir = (-sin theta sin phi, cos theta, sin theta cos phi)`. So v = 0 (row 0, the top)
//! is +y; with rotation 0, u = 0.5 (the image centre) looks along -z, u = 0.75 along +x,
//! u = 0.25 along -x and u = 0 along +z: seen from inside, the panorama is not mirrored.
//! `rotation` (degrees) turns the map about +y, counter-clockwise seen from above (the
//! right-hand rule: content at -z moves toward -x for +90). [`dir_to_uv`] inverts it:
//! `u = fract((atan2(-x, z) + rotation_radians) / (2 pi))`, `v = acos(y) / pi`.

use glam::Vec3;

use crate::scene::Environment;

/// The largest f32 below 1.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Rec. 709 luminance of linear RGB; 0 for a negative or non-finite result.
pub fn luminance(rgb: [f32; 3]) -> f32 {
    let y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
    sanitize(y)
}

/// A weight: negative and non-finite values become 0.
fn sanitize(v: f32) -> f32 {
    if v.is_finite() && v > 0.0 {
        v
    } else {
        0.0
    }
}

/// The normalised CDF (n + 1 values, 0 first, exactly 1.0 last) of `func` and its
/// integral over [0,1); uniform when the integral is 0.
fn build_cdf(func: &[f32]) -> (Vec<f32>, f32) {
    let n = func.len().max(1);
    let mut sums = Vec::with_capacity(n + 1);
    let mut acc = 0.0f64;
    sums.push(0.0f64);
    for &f in func {
        acc += f64::from(sanitize(f));
        sums.push(acc);
    }
    if func.is_empty() {
        sums.push(0.0);
    }
    let integral = acc / n as f64;
    let cdf = if acc > 0.0 {
        sums.iter().map(|&s| (s / acc) as f32).collect::<Vec<_>>()
    } else {
        (0..=n).map(|i| (i as f64 / n as f64) as f32).collect()
    };
    let mut cdf = cdf;
    cdf[0] = 0.0;
    cdf[n] = 1.0;
    (cdf, integral as f32)
}

/// The largest `i` in `0..n` (`n = cdf.len() - 1` cells) with `cdf[i] <= u`, by binary
/// search in at most `floor(log2(n)) + 1` iterations. Expects `cdf[0] <= u`.
pub fn find_interval(cdf: &[f32], u: f32) -> usize {
    let n = cdf.len().saturating_sub(1).max(1);
    let (mut lo, mut hi) = (0usize, n);
    // Invariant: cdf[lo] <= u, and hi == n or cdf[hi] > u.
    let max_iters = (usize::BITS - n.leading_zeros()) as usize; // floor(log2 n) + 1
    for _ in 0..max_iters {
        if hi - lo <= 1 {
            break;
        }
        let mid = (lo + hi) / 2;
        if cdf[mid] <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Samples the piecewise-constant density of `cdf` (n + 1 values): the position in
/// [0,1), its density and the cell.
fn sample_cdf(cdf: &[f32], u: f32) -> (f32, f32, usize) {
    let n = cdf.len() - 1;
    let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, ONE_MINUS_EPSILON) };
    let i = find_interval(cdf, u);
    let width = cdf[i + 1] - cdf[i];
    let du = if width > 0.0 { (u - cdf[i]) / width } else { 0.0 };
    let x = ((i as f32 + du) / n as f32).min(ONE_MINUS_EPSILON);
    (x, width * n as f32, i)
}

/// The cell of position `x` among `n` cells (clamped to the range).
fn cell_of(x: f32, n: usize) -> usize {
    let c = (x * n as f32).floor();
    if c.is_nan() || c < 0.0 {
        0
    } else {
        (c as usize).min(n - 1)
    }
}

/// The density of `cdf` (n + 1 values) at position `x`.
fn pdf_cdf(cdf: &[f32], x: f32) -> f32 {
    let n = cdf.len() - 1;
    let i = cell_of(x, n);
    (cdf[i + 1] - cdf[i]) * n as f32
}

/// A piecewise-constant density on [0,1) with n cells, built from n non-negative weights.
#[derive(Debug, Clone)]
pub struct Distribution1D {
    /// n + 1 values: 0 first, exactly 1.0 last, non-decreasing.
    cdf: Vec<f32>,
    /// Integral of the weights over [0,1): their sum / n.
    integral: f32,
}

impl Distribution1D {
    /// The distribution proportional to `func` (negative and non-finite weights count as
    /// 0; all-0 or empty gives the uniform distribution, with one cell when empty).
    pub fn new(func: &[f32]) -> Self {
        let (cdf, integral) = build_cdf(func);
        Distribution1D { cdf, integral }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cdf.len() - 1
    }

    /// Never true: an empty function gets one cell.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The CDF: `len() + 1` values.
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// Integral of the (sanitised) weights over [0,1).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// The position in [0,1) for `u` in [0,1), its density and its cell.
    pub fn sample(&self, u: f32) -> (f32, f32, usize) {
        sample_cdf(&self.cdf, u)
    }

    /// The density at `x` (clamped into [0,1)).
    pub fn pdf(&self, x: f32) -> f32 {
        pdf_cdf(&self.cdf, x)
    }
}

/// A piecewise-constant density on [0,1)^2 with W x H cells: a marginal distribution
/// over rows and one conditional distribution per row.
#[derive(Debug, Clone)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    marginal: Distribution1D,
    conditional: Vec<Distribution1D>,
}

impl Distribution2D {
    /// The distribution proportional to `func`, row-major with `width * height` values
    /// (row 0 is v in [0, 1/H)). Missing values count as 0, extra ones are ignored; a
    /// side of 0 counts as 1.
    pub fn new(width: usize, height: usize, func: &[f32]) -> Self {
        let (width, height) = (width.max(1), height.max(1));
        let conditional: Vec<Distribution1D> = (0..height)
            .map(|y| {
                let row: Vec<f32> = (0..width).map(|x| func.get(y * width + x).copied().unwrap_or(0.0)).collect();
                Distribution1D::new(&row)
            })
            .collect();
        let row_integrals: Vec<f32> = conditional.iter().map(|d| d.integral).collect();
        let marginal = Distribution1D::new(&row_integrals);
        Distribution2D { width, height, marginal, conditional }
    }

    /// The sampling distribution of an environment map: luminance times sin(theta) at
    /// the row centre (module docs).
    pub fn from_environment(env: &Environment) -> Self {
        let (w, h) = (env.width as usize, env.height as usize);
        let func: Vec<f32> = (0..w * h)
            .map(|i| {
                let y = i / w.max(1);
                let theta = std::f32::consts::PI * (y as f32 + 0.5) / h as f32;
                luminance(env.texels.get(i).copied().unwrap_or([0.0; 3])) * theta.sin()
            })
            .collect();
        Self::new(w, h, &func)
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Integral of the weights over [0,1)^2: their sum / (W H).
    pub fn integral(&self) -> f32 {
        self.marginal.integral
    }

    /// A point in [0,1)^2 (u1 picks the column, u2 the row) and its density per unit area.
    pub fn sample(&self, u1: f32, u2: f32) -> ([f32; 2], f32) {
        let (v, pdf_v, y) = self.marginal.sample(u2);
        let (u, pdf_u, _) = self.conditional[y].sample(u1);
        ([u, v], pdf_u * pdf_v)
    }

    /// The density per unit area at `uv` (clamped into [0,1)^2).
    pub fn pdf(&self, uv: [f32; 2]) -> f32 {
        let y = cell_of(uv[1], self.height);
        self.conditional[y].pdf(uv[0]) * self.marginal.pdf(uv[1])
    }

    /// The flat array the GPU kernel samples; layout in the module docs.
    pub fn gpu_rows(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(flat_len(self.width, self.height));
        out.extend_from_slice(&self.marginal.cdf);
        out.push(self.marginal.integral);
        for row in &self.conditional {
            out.extend_from_slice(&row.cdf);
        }
        out
    }
}

/// Length in floats of the flat array of a W x H distribution.
pub fn flat_len(width: usize, height: usize) -> usize {
    (height + 1) + 1 + height * (width + 1)
}

/// Row y's conditional CDF inside the flat array.
fn flat_row(rows: &[f32], width: usize, height: usize, y: usize) -> &[f32] {
    let start = height + 2 + y * (width + 1);
    &rows[start..start + width + 1]
}

/// [`Distribution2D::sample`] from the flat array of [`Distribution2D::gpu_rows`] alone,
/// as the GPU kernel does it. Panics if `rows` is shorter than [`flat_len`].
pub fn sample_flat(rows: &[f32], width: usize, height: usize, u1: f32, u2: f32) -> ([f32; 2], f32) {
    let marginal = &rows[..height + 1];
    let (v, pdf_v, y) = sample_cdf(marginal, u2);
    let (u, pdf_u, _) = sample_cdf(flat_row(rows, width, height, y), u1);
    ([u, v], pdf_u * pdf_v)
}

/// [`Distribution2D::pdf`] from the flat array alone.
pub fn pdf_flat(rows: &[f32], width: usize, height: usize, uv: [f32; 2]) -> f32 {
    let marginal = &rows[..height + 1];
    let y = cell_of(uv[1], height);
    pdf_cdf(flat_row(rows, width, height, y), uv[0]) * pdf_cdf(marginal, uv[1])
}

/// The density per solid angle of a direction whose uv density is `pdf_uv`:
/// `pdf_uv / (2 pi^2 sin theta)`; 0 where `sin_theta <= 0`.
pub fn pdf_solid_angle(pdf_uv: f32, sin_theta: f32) -> f32 {
    if sin_theta > 0.0 {
        pdf_uv / (2.0 * std::f32::consts::PI * std::f32::consts::PI * sin_theta)
    } else {
        0.0
    }
}

/// The unit direction of map position `uv` for a map turned by `rotation_deg` about +y
/// (module docs).
pub fn uv_to_dir(uv: [f32; 2], rotation_deg: f32) -> Vec3 {
    let phi = 2.0 * std::f32::consts::PI * uv[0] - rotation_deg.to_radians();
    let theta = std::f32::consts::PI * uv[1];
    let (sin_t, cos_t) = theta.sin_cos();
    let (sin_p, cos_p) = phi.sin_cos();
    Vec3::new(-sin_t * sin_p, cos_t, sin_t * cos_p)
}

/// The map position of unit direction `dir` for a map turned by `rotation_deg` about +y:
/// u in \[0,1), v in \[0,1\] (module docs).
pub fn dir_to_uv(dir: Vec3, rotation_deg: f32) -> [f32; 2] {
    let tau = 2.0 * std::f32::consts::PI;
    let phi = (-dir.x).atan2(dir.z) + rotation_deg.to_radians();
    let mut u = (phi / tau).rem_euclid(1.0);
    if u >= 1.0 {
        u = 0.0;
    }
    let v = dir.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    [u, v]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64: a seeded generator of uniform f32 in [0,1).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// A 32x16 map: a gradient, a bright spot, an all-black row and a black column.
    fn test_map() -> (usize, usize, Vec<f32>) {
        let (w, h) = (32, 16);
        let mut f = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut v = 0.05 + x as f32 / w as f32 + 0.5 * y as f32 / h as f32;
                if (10..13).contains(&x) && (4..6).contains(&y) {
                    v += 40.0;
                }
                if y == 9 || x == 20 {
                    v = 0.0;
                }
                f[y * w + x] = v;
            }
        }
        (w, h, f)
    }

    #[test]
    fn cdf_layout_and_small_example() {
        let d = Distribution2D::new(2, 1, &[1.0, 3.0]);
        assert_eq!(d.gpu_rows(), vec![0.0, 1.0, 2.0, 0.0, 0.25, 1.0]);
        let (w, h, f) = test_map();
        let d = Distribution2D::new(w, h, &f);
        let rows = d.gpu_rows();
        assert_eq!(rows.len(), flat_len(w, h));
        assert_eq!(rows[h], 1.0);
        for y in 0..h {
            let r = flat_row(&rows, w, h, y);
            assert_eq!((r[0], r[w]), (0.0, 1.0));
            assert!(r.windows(2).all(|p| p[0] <= p[1]));
        }
    }

    #[test]
    fn pdf_integrates_to_one() {
        let (w, h, f) = test_map();
        let maps = [Distribution2D::new(w, h, &f), Distribution2D::new(w, h, &vec![0.0; w * h])];
        for d in maps {
            let mut sum = 0.0f64;
            for y in 0..h {
                for x in 0..w {
                    let uv = [(x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32];
                    sum += f64::from(d.pdf(uv));
                }
            }
            let integral = sum / (w * h) as f64;
            assert!((integral - 1.0).abs() < 1e-5, "{integral}");
        }
    }

    #[test]
    fn all_zero_and_bad_weights_are_uniform() {
        let d = Distribution2D::new(4, 3, &[0.0; 12]);
        assert_eq!(d.integral(), 0.0);
        let (uv, pdf) = d.sample(0.3, 0.7);
        assert!((pdf - 1.0).abs() < 1e-6, "{pdf}");
        assert!((uv[0] - 0.3).abs() < 1e-6 && (uv[1] - 0.7).abs() < 1e-6, "{uv:?}");
        let d = Distribution1D::new(&[f32::NAN, -1.0, f32::INFINITY, 2.0]);
        assert_eq!(d.cdf(), &[0.0, 0.0, 0.0, 0.0, 1.0]);
        let (x, pdf, i) = d.sample(0.5);
        assert_eq!((i, pdf), (3, 4.0));
        assert!((x - 0.875).abs() < 1e-6);
        assert_eq!(Distribution1D::new(&[]).len(), 1);
        // A zero row in a non-zero map is never chosen and is uniform inside.
        let (w, h, f) = test_map();
        let d = Distribution2D::new(w, h, &f);
        assert_eq!(d.pdf([0.5, 9.5 / h as f32]), 0.0);
        assert_eq!(flat_row(&d.gpu_rows(), w, h, 9)[1], 1.0 / w as f32);
    }

    #[test]
    fn binary_search_finds_the_largest_interval_within_its_bound() {
        let cdf = [0.0, 0.25, 0.25, 0.25, 0.5, 1.0];
        assert_eq!(find_interval(&cdf, 0.0), 0);
        assert_eq!(find_interval(&cdf, 0.25), 3);
        assert_eq!(find_interval(&cdf, 0.49), 3);
        assert_eq!(find_interval(&cdf, 0.5), 4);
        assert_eq!(find_interval(&cdf, ONE_MINUS_EPSILON), 4);
        let mut rng = Rng(3);
        for n in 1..70 {
            let f: Vec<f32> = (0..n).map(|i| if i % 3 == 1 { 0.0 } else { rng.next() }).collect();
            let d = Distribution1D::new(&f);
            for _ in 0..50 {
                let u = rng.next();
                let i = find_interval(d.cdf(), u);
                let want = (0..n).rev().find(|&j| d.cdf()[j] <= u).unwrap_or(0);
                assert_eq!(i, want, "n {n} u {u}");
                assert!(d.cdf()[i + 1] > u);
            }
        }
    }

    #[test]
    fn sample_pdf_matches_pdf_and_flat_path_agrees() {
        let (w, h, f) = test_map();
        let d = Distribution2D::new(w, h, &f);
        let rows = d.gpu_rows();
        let mut rng = Rng(7);
        let mut near_edge = 0;
        for _ in 0..20_000 {
            let (u1, u2) = (rng.next(), rng.next());
            let (uv, pdf) = d.sample(u1, u2);
            let (uv_flat, pdf_flat_s) = sample_flat(&rows, w, h, u1, u2);
            assert_eq!((uv, pdf), (uv_flat, pdf_flat_s), "u = ({u1}, {u2})");
            assert!(pdf > 0.0 && (0.0..1.0).contains(&uv[0]) && (0.0..1.0).contains(&uv[1]));
            assert_eq!(d.pdf(uv), pdf_flat(&rows, w, h, uv));
            // The cell lookup of a point on a cell edge can round into the neighbour.
            let edge = |t: f32, n: usize| {
                let s = t * n as f32;
                (s - s.round()).abs() < 1e-4
            };
            if edge(uv[0], w) || edge(uv[1], h) {
                near_edge += 1;
                continue;
            }
            assert!((d.pdf(uv) - pdf).abs() <= 1e-6 * pdf, "uv {uv:?}: {} vs {pdf}", d.pdf(uv));
        }
        assert!(near_edge < 100, "{near_edge}");
    }

    /// Upper 0.001 quantile of chi-square with `k` degrees of freedom (Wilson-Hilferty;
    /// within 1% of the table for k >= 10).
    fn chi2_critical_p001(k: f64) -> f64 {
        let z = 3.090_232; // upper 0.001 quantile of the standard normal
        let a = 2.0 / (9.0 * k);
        k * (1.0 - a + z * a.sqrt()).powi(3)
    }

    /// The chi-square statistic and degrees of freedom of `counts` against
    /// probabilities `p` (cells with expected count < 5 pooled). Panics if a cell of
    /// probability 0 was hit.
    fn chi2(counts: &[u64], p: &[f64], n: u64) -> (f64, f64) {
        let mut bins: Vec<(f64, f64)> = Vec::new(); // (expected, observed)
        let (mut pooled_e, mut pooled_o) = (0.0, 0.0);
        for (&c, &p) in counts.iter().zip(p) {
            let e = p * n as f64;
            if p == 0.0 {
                assert_eq!(c, 0, "a cell of probability 0 was sampled");
            } else if e < 5.0 {
                pooled_e += e;
                pooled_o += c as f64;
            } else {
                bins.push((e, c as f64));
            }
        }
        if pooled_e >= 5.0 {
            bins.push((pooled_e, pooled_o));
        } else if let Some(last) = bins.last_mut() {
            last.0 += pooled_e;
            last.1 += pooled_o;
        }
        let stat = bins.iter().map(|&(e, o)| (o - e) * (o - e) / e).sum();
        (stat, bins.len() as f64 - 1.0)
    }

    #[test]
    fn chi_square_histogram_matches_cell_probabilities() {
        let (w, h, f) = test_map();
        let d = Distribution2D::new(w, h, &f);
        let total: f64 = f.iter().map(|&v| f64::from(v)).sum();
        let p: Vec<f64> = f.iter().map(|&v| f64::from(v) / total).collect();
        let n = 200_000u64;
        let mut rng = Rng(0x5EED);
        let mut counts = vec![0u64; w * h];
        let mut uniform = vec![0u64; w * h];
        for _ in 0..n {
            let (uv, _) = d.sample(rng.next(), rng.next());
            counts[cell_of(uv[1], h) * w + cell_of(uv[0], w)] += 1;
            let (x, y) = (cell_of(rng.next(), w), cell_of(rng.next(), h));
            if p[y * w + x] > 0.0 {
                uniform[y * w + x] += 1;
            }
        }
        let (stat, dof) = chi2(&counts, &p, n);
        let critical = chi2_critical_p001(dof);
        assert!(stat < critical, "chi-square {stat:.1} >= {critical:.1} ({dof} degrees of freedom)");
        // The test has power: uniform samples fail it by far.
        let m = uniform.iter().sum();
        let (stat, dof) = chi2(&uniform, &p, m);
        assert!(stat > 10.0 * chi2_critical_p001(dof), "{stat}");
    }

    #[test]
    fn environment_weights_luminance_and_sin_theta() {
        let env = Environment {
            name: "test".into(),
            width: 2,
            height: 2,
            texels: vec![[1.0, 1.0, 1.0], [0.0, 1.0, 0.0], [f32::NAN, 0.0, 0.0], [-1.0, -1.0, -1.0]],
            rotation: 30.0,
            intensity: 5.0,
        };
        let d = Distribution2D::from_environment(&env);
        // Only the top row has weight: 1 and 0.7152, times sin(pi/4).
        let s = (std::f32::consts::PI / 4.0).sin();
        assert!((d.integral() - (1.0 + 0.7152) * s / 4.0).abs() < 1e-6);
        let rows = d.gpu_rows();
        assert_eq!(&rows[..3], &[0.0, 1.0, 1.0]);
        assert!((rows[5] - 1.0 / 1.7152).abs() < 1e-6);
    }

    #[test]
    fn direction_convention() {
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
        assert!(close(uv_to_dir([0.5, 0.5], 0.0), Vec3::NEG_Z));
        assert!(close(uv_to_dir([0.75, 0.5], 0.0), Vec3::X));
        assert!(close(uv_to_dir([0.25, 0.5], 0.0), Vec3::NEG_X));
        assert!(close(uv_to_dir([0.0, 0.5], 0.0), Vec3::Z));
        assert!(close(uv_to_dir([0.3, 0.0], 0.0), Vec3::Y));
        assert!(close(uv_to_dir([0.3, 1.0], 0.0), Vec3::NEG_Y));
        // +90 degrees, counter-clockwise from above: the centre (-z) moves to -x.
        assert!(close(uv_to_dir([0.5, 0.5], 90.0), Vec3::NEG_X));
        let uv = dir_to_uv(Vec3::NEG_Z, 0.0);
        assert!((uv[0] - 0.5).abs() < 1e-6 && (uv[1] - 0.5).abs() < 1e-6, "{uv:?}");
        let uv = dir_to_uv(Vec3::NEG_X, 90.0);
        assert!((uv[0] - 0.5).abs() < 1e-6 && (uv[1] - 0.5).abs() < 1e-6, "{uv:?}");
    }

    #[test]
    fn direction_round_trips() {
        let mut rng = Rng(11);
        for i in 0..5000 {
            let rotation = [0.0, 30.0, -75.5, 180.0, 721.0][i % 5];
            let uv = [rng.next(), 0.001 + 0.998 * rng.next()];
            let d = uv_to_dir(uv, rotation);
            assert!((d.length() - 1.0).abs() < 1e-5);
            let back = dir_to_uv(d, rotation);
            let du = (back[0] - uv[0]).abs();
            assert!(du.min(1.0 - du) < 1e-4 && (back[1] - uv[1]).abs() < 1e-4, "{uv:?} -> {back:?}");
            assert!((0.0..1.0).contains(&back[0]));
            let mut v = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
            if v.length() < 1e-3 {
                continue;
            }
            v = v.normalize();
            assert!((uv_to_dir(dir_to_uv(v, rotation), rotation) - v).length() < 1e-4, "{v}");
        }
    }

    #[test]
    fn solid_angle_density_integrates_to_one() {
        // The uniform uv density, converted per solid angle, integrates to 1 over the sphere.
        let n = 400;
        let mut sum = 0.0f64;
        for j in 0..n {
            let theta = std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
            let p = pdf_solid_angle(1.0, theta.sin() as f32) as f64;
            // d omega = sin theta d theta d phi, integrated over phi: 2 pi.
            sum += p * theta.sin() * (std::f64::consts::PI / n as f64) * 2.0 * std::f64::consts::PI;
        }
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
        assert_eq!(pdf_solid_angle(1.0, 0.0), 0.0);
    }
}
