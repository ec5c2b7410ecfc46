//! `arbor._arbor`, the Rust half of the Python module `arbor` (docs/python.md): thin
//! wrappers over the library's ray casting (`arbor::raycast`), scene loading and
//! rendering. The Python half (`python/arbor/__init__.py`) checks shapes and dtypes,
//! converts arrays to contiguous float32 or uint32 and shapes the outputs; this half
//! takes flat arrays.
//!
//! - Device work runs with the GIL released; Ctrl-C is checked between pieces of a
//!   cast and between sample waves of a render, and raises `KeyboardInterrupt`.
//! - A scene's calls take turns (a mutex), and so does device work on one device: a
//!   scene may be used from several threads. Every lock is taken with the GIL released
//!   (a thread holding one may take the GIL to poll for Ctrl-C).
//! - Errors: arbor's message in a `ValueError` (bad input), `FileNotFoundError` or
//!   `OSError` (files), or `RuntimeError` (no device, a device failure).

use std::sync::{Arc, Mutex, MutexGuard};

use arbor::accel::{AccelKind, AccelParams, BuildOn};
use arbor::gpu::{Context, ContextOptions};
use arbor::raycast::RaycastingScene as Casting;
use arbor::render::{Control, Integrator, RenderSettings};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// Flat numpy arrays handed to Python.
type F32s<'py> = Bound<'py, PyArray1<f32>>;
type U32s<'py> = Bound<'py, PyArray1<u32>>;

/// arbor's error as the Python exception a user expects.
fn py_err(e: arbor::Error) -> PyErr {
    use arbor::Error as E;
    let msg = e.to_string();
    match e {
        E::Usage(_) | E::BadRay { .. } | E::Parse { .. } | E::Invalid { .. } | E::Scene { .. } => {
            PyValueError::new_err(msg)
        }
        E::Io { cause, .. } if cause.kind() == std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(msg),
        E::Io { .. } => PyOSError::new_err(msg),
        _ => PyRuntimeError::new_err(msg),
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// An open device, shared by every scene and render that names it.
struct Device {
    name: Option<String>,
    ctx: Mutex<Context>,
}

static DEVICES: Mutex<Vec<Arc<Device>>> = Mutex::new(Vec::new());

/// The device `name` picks (an index or part of a name; `None`: the first discrete
/// GPU, else the first device), opened once. `ARBOR_VALIDATION=1` turns the Khronos
/// validation layer on, as for the command line.
fn device(name: Option<&str>) -> arbor::Result<Arc<Device>> {
    let mut list = lock(&DEVICES);
    if let Some(d) = list.iter().find(|d| d.name.as_deref() == name) {
        return Ok(d.clone());
    }
    let validation = std::env::var("ARBOR_VALIDATION").is_ok_and(|v| v == "1");
    let ctx = Context::new(&ContextOptions { device: name.map(String::from), validation, ..Default::default() })?;
    let d = Arc::new(Device { name: name.map(String::from), ctx: Mutex::new(ctx) });
    list.push(d.clone());
    Ok(d)
}

/// Runs `work` with the device's context (device work on one device takes turns),
/// then fails if the validation layer reported an error meanwhile.
fn with_device<T>(name: Option<&str>, work: impl FnOnce(&Context) -> arbor::Result<T>) -> arbor::Result<T> {
    let d = device(name)?;
    let ctx = lock(&d.ctx);
    let out = work(&ctx);
    let reported = ctx.take_validation_errors();
    if let Some(first) = reported.first() {
        return Err(arbor::Error::Validation { count: reported.len(), first: first.clone() });
    }
    out
}

/// Checks for Ctrl-C (and other signals) from device work running without the GIL:
/// the first error Python raised is kept in `pending`, and arbor's work is stopped.
fn check_signals(pending: &Mutex<Option<PyErr>>) -> bool {
    match Python::attach(|py| py.check_signals()) {
        Ok(()) => false,
        Err(e) => {
            lock(pending).get_or_insert(e);
            true
        }
    }
}

/// The outcome of work that `pending` may have interrupted: the signal's exception
/// first.
fn finish<T>(out: arbor::Result<T>, pending: Mutex<Option<PyErr>>) -> PyResult<T> {
    if let Some(e) = pending.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(e);
    }
    out.map_err(py_err)
}

fn interrupted() -> arbor::Error {
    arbor::Error::Failed("interrupted".into())
}

/// `(N, width)` C-contiguous rows as a copy (taken with the GIL held, so that Python
/// code cannot write into them while the device reads them).
fn rows<T: numpy::Element + bytemuck::Pod, const W: usize>(
    name: &str,
    a: &PyReadonlyArray2<'_, T>,
) -> PyResult<Vec<[T; W]>>
where
    [T; W]: bytemuck::Pod,
{
    if a.shape()[1] != W {
        return Err(PyValueError::new_err(format!("{name} must have shape (N, {W}), got {:?}", a.shape())));
    }
    let flat = a.as_slice().map_err(|_| PyValueError::new_err(format!("{name} must be C-contiguous")))?;
    Ok(bytemuck::cast_slice(flat).to_vec())
}

fn parse_build(build: &str) -> PyResult<BuildOn> {
    build.parse().map_err(|e: String| PyValueError::new_err(format!("build {build:?}: {e}")))
}

fn parse_kind(accel: &str) -> PyResult<Option<AccelKind>> {
    if accel == "auto" {
        return Ok(None);
    }
    accel.parse().map(Some).map_err(|e: String| PyValueError::new_err(format!("accel {accel:?}: {e}, or auto")))
}

/// A scene to cast rays into (`arbor.RaycastingScene` wraps it).
#[pyclass(module = "arbor._arbor", name = "RaycastingScene")]
struct RaycastingScene {
    inner: Mutex<Casting>,
    device: Option<String>,
    /// A GPU build or the driver's structure: built with the device.
    needs_device: bool,
}

#[pymethods]
impl RaycastingScene {
    #[new]
    #[pyo3(signature = (accel = "auto", build = "cpu", device = None))]
    fn new(accel: &str, build: &str, device: Option<String>) -> PyResult<Self> {
        let build = parse_build(build)?;
        let kind = parse_kind(accel)?;
        let params = AccelParams { build, ..Default::default() };
        let inner = match kind {
            Some(k) => Casting::new(k, params),
            None => Casting::auto(params),
        };
        let needs_device = build == BuildOn::Gpu || kind == Some(AccelKind::RayQuery);
        Ok(RaycastingScene { inner: Mutex::new(inner), device, needs_device })
    }

    /// The structure's name: the one asked for, or auto's choice once built (None
    /// before).
    #[getter]
    fn accel(&self, py: Python<'_>) -> Option<&'static str> {
        py.detach(|| lock(&self.inner).kind().map(AccelKind::name))
    }

    fn add_triangles(
        &self,
        py: Python<'_>,
        vertices: PyReadonlyArray2<'_, f32>,
        triangles: PyReadonlyArray2<'_, u32>,
    ) -> PyResult<u32> {
        let v = rows::<f32, 3>("vertices", &vertices)?;
        let t = rows::<u32, 3>("triangles", &triangles)?;
        py.detach(|| lock(&self.inner).add_triangles(&v, &t)).map_err(py_err)
    }

    fn add_sphere(&self, py: Python<'_>, center: [f32; 3], radius: f32) -> PyResult<u32> {
        py.detach(|| lock(&self.inner).add_sphere(center, radius)).map_err(py_err)
    }

    /// Builds the structure now; its statistics as JSON.
    fn build(&self, py: Python<'_>) -> PyResult<String> {
        let stats = py
            .detach(|| {
                let mut scene = lock(&self.inner);
                if self.needs_device {
                    with_device(self.device.as_deref(), |ctx| scene.build_on(ctx))
                } else {
                    scene.build()
                }
            })
            .map_err(py_err)?;
        serde_json::to_string(&stats).map_err(|e| PyRuntimeError::new_err(e.to_string()))
    }

    /// Closest hits: t_hit, geometry_ids, primitive_ids, primitive_uvs (flat),
    /// primitive_normals (flat).
    #[pyo3(signature = (rays, cpu = false))]
    fn cast_rays<'py>(
        &self,
        py: Python<'py>,
        rays: PyReadonlyArray2<'py, f32>,
        cpu: bool,
    ) -> PyResult<(F32s<'py>, U32s<'py>, U32s<'py>, F32s<'py>, F32s<'py>)> {
        let rays = rows::<f32, 6>("rays", &rays)?;
        let pending = Mutex::new(None);
        let out = py.detach(|| {
            let mut scene = lock(&self.inner);
            if cpu {
                return scene.cast_rays_cpu(&rays);
            }
            with_device(self.device.as_deref(), |ctx| {
                scene.cast_rays_with(ctx, &rays, &mut |_| {
                    if check_signals(&pending) {
                        Err(interrupted())
                    } else {
                        Ok(())
                    }
                })
            })
        });
        let r = finish(out, pending)?;
        Ok((
            r.t_hit.into_pyarray(py),
            r.geometry_ids.into_pyarray(py),
            r.primitive_ids.into_pyarray(py),
            r.primitive_uvs.into_flattened().into_pyarray(py),
            r.primitive_normals.into_flattened().into_pyarray(py),
        ))
    }

    fn test_occlusions<'py>(
        &self,
        py: Python<'py>,
        rays: PyReadonlyArray2<'py, f32>,
        tnear: f32,
        tfar: f32,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let rays = rows::<f32, 6>("rays", &rays)?;
        let pending = Mutex::new(None);
        let out = py.detach(|| {
            let mut scene = lock(&self.inner);
            with_device(self.device.as_deref(), |ctx| {
                scene.test_occlusions_with(ctx, &rays, tnear, tfar, &mut |_| {
                    if check_signals(&pending) {
                        Err(interrupted())
                    } else {
                        Ok(())
                    }
                })
            })
        });
        Ok(finish(out, pending)?.into_pyarray(py))
    }
}

/// A loaded scene (`arbor.load`).
#[pyclass(module = "arbor._arbor", name = "Scene", frozen)]
struct Scene {
    inner: Arc<arbor::Scene>,
}

#[pymethods]
impl Scene {
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }
    #[getter]
    fn triangles(&self) -> u64 {
        self.inner.stored_triangles()
    }
    #[getter]
    fn spheres(&self) -> usize {
        self.inner.spheres.len()
    }
    #[getter]
    fn instances(&self) -> bool {
        self.inner.has_instances()
    }
    /// The scene's own image size (width, height).
    #[getter]
    fn size(&self) -> (u32, u32) {
        (self.inner.width, self.inner.height)
    }
    /// What the loader dropped or approximated, one line each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings.clone()
    }
    /// The scene's triangles as arrays: vertices (V x 3 float32, flat) and triangles
    /// (F x 3 uint32, flat); instances are drawn out as copies.
    fn mesh<'py>(&self, py: Python<'py>) -> PyResult<(F32s<'py>, U32s<'py>)> {
        let flat;
        let scene: &arbor::Scene = if self.inner.has_instances() {
            flat = py.detach(|| self.inner.flattened()).map_err(py_err)?;
            &flat
        } else {
            &self.inner
        };
        let v: Vec<f32> = scene.positions.iter().flat_map(|p| p.to_array()).collect();
        let t: Vec<u32> = scene.triangles.iter().flatten().copied().collect();
        Ok((v.into_pyarray(py), t.into_pyarray(py)))
    }
    fn __repr__(&self) -> String {
        format!(
            "arbor.Scene({:?}: {} triangles, {} spheres, {}x{})",
            self.inner.name,
            self.inner.stored_triangles(),
            self.inner.spheres.len(),
            self.inner.width,
            self.inner.height
        )
    }
}

#[pyfunction]
fn load(py: Python<'_>, source: String) -> PyResult<Scene> {
    let scene = py.detach(|| arbor::Scene::load(&source)).map_err(py_err)?;
    Ok(Scene { inner: Arc::new(scene) })
}

/// The devices as JSON (`arbor.devices()` shapes it).
#[pyfunction]
fn devices(py: Python<'_>) -> PyResult<String> {
    let list = py.detach(Context::list_devices).map_err(py_err)?;
    serde_json::to_string(&list).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

/// A render's image and AOVs, flat (a dict for Python).
#[derive(IntoPyObject)]
struct Rendered<'py> {
    width: u32,
    height: u32,
    accel: &'static str,
    image: F32s<'py>,
    depth: F32s<'py>,
    normal: F32s<'py>,
    albedo: F32s<'py>,
    prim: U32s<'py>,
    variance: F32s<'py>,
    samples: U32s<'py>,
}

#[pyfunction]
#[pyo3(signature = (scene, width, height, spp, integrator, accel, seed, max_depth, device))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    scene: &Scene,
    width: Option<u32>,
    height: Option<u32>,
    spp: u32,
    integrator: &str,
    accel: &str,
    seed: u32,
    max_depth: Option<u32>,
    device: Option<String>,
) -> PyResult<Rendered<'py>> {
    let integrator = Integrator::parse(integrator)
        .ok_or_else(|| PyValueError::new_err(format!("integrator {integrator:?}: expected path, whitted or sppm")))?;
    let kind = parse_kind(accel)?;
    let source = scene.inner.clone();
    let (w, h) = (width.unwrap_or(source.width), height.unwrap_or(source.height));
    let mut settings = RenderSettings::for_size(w, h);
    settings.integrator = integrator;
    settings.spp = spp;
    settings.seed = seed;
    settings.max_depth = max_depth;
    let pending = Mutex::new(None);
    let out = py.detach(|| {
        with_device(device.as_deref(), |ctx| {
            // `auto` as the command line resolves it: the device's costs and limits.
            (settings.accel, settings.params.build) = match kind {
                Some(k) => (k, BuildOn::Cpu),
                None => {
                    let (costs, _) = arbor::accel::calibrate::device_costs(ctx.info());
                    let fit = arbor::accel::auto::Fit::of(ctx);
                    arbor::accel::auto::choose_on(&source, u64::from(w) * u64::from(h), spp, &fit, &costs, None)?.0
                }
            };
            let flat;
            let scene: &arbor::Scene = if source.has_instances() && settings.accel.is_brute_force() {
                flat = source.flattened()?;
                &flat
            } else {
                &source
            };
            arbor::accel::check_build(settings.accel, scene, settings.params.build)?;
            settings.check()?;
            let control = Control {
                progress: Box::new(|_, _| {}),
                interrupted: Box::new(|| check_signals(&pending)),
                checkpoint: None,
            };
            let (frame, _) = arbor::render::gpu::render_controlled(ctx, scene, &settings, control)?;
            Ok(frame)
        })
    });
    let frame = finish(out, pending)?;
    Ok(Rendered {
        width: frame.width,
        height: frame.height,
        accel: settings.accel.name(),
        image: frame.radiance.into_flattened().into_pyarray(py),
        depth: frame.depth.into_pyarray(py),
        normal: frame.normal.into_flattened().into_pyarray(py),
        albedo: frame.albedo.into_flattened().into_pyarray(py),
        prim: frame.prim.into_pyarray(py),
        variance: frame.variance.into_pyarray(py),
        samples: frame.samples.into_pyarray(py),
    })
}

/// An image file as linear RGB: (width, height, flat rows).
#[pyfunction]
fn read_image(py: Python<'_>, path: std::path::PathBuf) -> PyResult<(u32, u32, F32s<'_>)> {
    let (w, h, rgb) = py.detach(|| arbor::render::output::compare::read_linear(&path)).map_err(py_err)?;
    Ok((w, h, rgb.into_flattened().into_pyarray(py)))
}

#[pymodule]
fn _arbor(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("INVALID_ID", arbor::raycast::INVALID_ID)?;
    m.add("CAST_PIECE", arbor::raycast::CAST_PIECE)?;
    m.add("STRUCTURES", AccelKind::EVERY.iter().map(|k| k.name()).collect::<Vec<_>>())?;
    m.add_class::<RaycastingScene>()?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(devices, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    Ok(())
}
