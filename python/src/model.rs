//! `robocal.Model`: a robot model (a preset, a TOML model, a URDF chain) and its forward
//! kinematics, from the library's [`Chain`].

use crate::errors::{self, Kind};
use nalgebra::Matrix6xX;
use numpy::{
    PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use robocal::io::{self, UrdfChain};
use robocal::kinematics::{Chain, ChainAt};
use robocal::model::{ModelRef, PRESETS, RobotModel, UrdfOptions};
use std::path::Path;

/// A robot model with its nominal kinematics compiled once.
#[pyclass(module = "robocal", frozen)]
pub struct Model {
    /// The model.
    pub(crate) inner: RobotModel,
    /// Its URDF file, when it was read from one: the calibrated URDF is written from it.
    pub(crate) urdf: Option<UrdfChain>,
    /// The positions of its markers (their numbers, mm in the marker frame), if it carries
    /// any (a model file's `[[markers]]`, a calibration's).
    pub(crate) markers: Vec<(usize, nalgebra::Vector3<f64>)>,
    /// The chain at the nominal parameters.
    nominal: ChainAt,
}

impl Model {
    /// `model`, its chain compiled.
    pub(crate) fn new(inner: RobotModel, urdf: Option<UrdfChain>) -> Self {
        let nominal = Chain::new(&inner).with_errors(&vec![0.0; inner.params().len()]);
        Self { inner, urdf, markers: Vec::new(), nominal }
    }

    /// The model with its markers.
    pub(crate) fn with_markers(self, markers: Vec<(usize, nalgebra::Vector3<f64>)>) -> Self {
        Self { markers, ..self }
    }

    /// `q` as one value per joint, or an input error.
    fn joints<'a>(&self, q: &'a [f64], what: &str) -> PyResult<&'a [f64]> {
        if q.len() != self.inner.dof() {
            return Err(errors::argument(
                what,
                format!("{} values for the {} joints of {}", q.len(), self.inner.dof(), self.inner.name),
            ));
        }
        Ok(q)
    }
}

/// The 4 x 4 homogeneous transform of `pose`, row-major, into `out`.
fn homogeneous(pose: &nalgebra::Isometry3<f64>, out: &mut [f64]) {
    let m = pose.to_homogeneous();
    for (i, v) in out.iter_mut().enumerate() {
        *v = m[(i / 4, i % 4)];
    }
}

#[pymethods]
impl Model {
    /// A preset by name (`robocal.presets()` lists them).
    #[staticmethod]
    fn preset(name: &str) -> PyResult<Self> {
        RobotModel::preset(name).map(|m| Self::new(m, None)).ok_or_else(|| {
            let names: Vec<&str> = PRESETS.iter().map(|(n, _)| *n).collect();
            errors::argument("name", format!("no preset `{name}`: expected one of {}", names.join(", ")))
        })
    }

    /// A model from a TOML file's path, or from TOML text (text holds a newline or `=`).
    #[staticmethod]
    fn from_toml(path_or_text: &str) -> PyResult<Self> {
        if path_or_text.contains('\n') || path_or_text.contains('=') {
            let model = RobotModel::from_toml_str(path_or_text)
                .map_err(|e| errors::from_error(Kind::Input, &e, Some("the model text")))?;
            return Ok(Self::new(model, None));
        }
        let model = io::load_model(&ModelRef::named(path_or_text))
            .map_err(|e| errors::from_error(Kind::Input, &e, None))?;
        let markers = match std::fs::read_to_string(path_or_text) {
            Ok(text) => robocal::model::markers_from_toml_str(&text)
                .map_err(|e| errors::from_error(Kind::Input, &e, Some(path_or_text)))?,
            Err(_) => Vec::new(),
        };
        Ok(Self::new(model, None).with_markers(markers))
    }

    /// The chain of a URDF file from `base_link` to `tip_link` (by default the root link and
    /// the only leaf).
    #[staticmethod]
    #[pyo3(signature = (path, base_link=None, tip_link=None))]
    fn from_urdf(path: &str, base_link: Option<&str>, tip_link: Option<&str>) -> PyResult<Self> {
        let chain = io::load_urdf(Path::new(path), base_link, tip_link)
            .map_err(|e| errors::from_error(Kind::Input, &e, None))?;
        Ok(Self::new(chain.model.clone(), Some(chain)))
    }

    /// The model as TOML, as `robocal model show` prints it.
    fn to_toml(&self) -> String {
        self.inner.to_toml_string()
    }

    /// The model as URDF, as `robocal model urdf` writes it.
    #[pyo3(signature = (standard=false))]
    fn to_urdf(&self, standard: bool) -> String {
        robocal::model::to_urdf(&self.inner, UrdfOptions { standard }).urdf
    }

    /// The model's name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// The joints' names, in order.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// Number of joints.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// The error parameters' names (`j1.theta`, ..., `base.x`, ..., `tool.x`, ...).
    #[getter]
    fn parameter_names(&self) -> Vec<String> {
        self.inner.params().iter().map(|p| p.name.clone()).collect()
    }

    /// The tool pose at `q` (rad; mm for prismatic joints): a 4 x 4 transform in mm.
    fn fk<'py>(&self, py: Python<'py>, q: PyReadonlyArray1<'py, f64>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let q = q.as_array().to_vec();
        let q = self.joints(&q, "q")?;
        let mut out = vec![0.0; 16];
        homogeneous(&self.nominal.pose(q), &mut out);
        PyArray1::from_vec(py, out).reshape([4, 4])
    }

    /// The tool poses at each row of `q` (n x dof): n x 4 x 4, the GIL released meanwhile; a
    /// C-contiguous `q` is read in place.
    fn fk_batch<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let (n, dof) = (q.shape()[0], q.shape()[1]);
        self.joints(&vec![0.0; dof], "q's columns")?;
        let copied;
        let rows: &[f64] = match q.as_slice() {
            Ok(slice) => slice,
            Err(_) => {
                copied = q.as_array().iter().copied().collect::<Vec<f64>>();
                &copied
            }
        };
        let out = py.detach(|| {
            let mut out = vec![0.0; n * 16];
            for (q, out) in rows.chunks_exact(dof.max(1)).zip(out.chunks_exact_mut(16)) {
                homogeneous(&self.nominal.pose(q), out);
            }
            out
        });
        PyArray1::from_vec(py, out).reshape([n, 4, 4])
    }

    /// The manipulator Jacobian at `q`: 6 x dof, linear rows (mm per rad, or per mm) then
    /// angular rows (rad per rad, or per mm).
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let q = q.as_array().to_vec();
        let q = self.joints(&q, "q")?;
        let mut j = Matrix6xX::zeros(q.len());
        self.nominal.manipulator_jacobian(q, &mut j);
        let rows: Vec<Vec<f64>> = (0..6).map(|r| j.row(r).iter().copied().collect()).collect();
        Ok(PyArray2::from_vec2(py, &rows).expect("6 rows of dof values"))
    }

    fn __repr__(&self) -> String {
        format!("robocal.Model({:?}, {} joints)", self.inner.name, self.inner.dof())
    }
}

/// The names of the preset models.
#[pyfunction]
pub fn presets() -> Vec<&'static str> {
    PRESETS.iter().map(|(n, _)| *n).collect()
}
