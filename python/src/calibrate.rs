//! `robocal.calibrate`: the library's calibration of marker data (arrays, a DataFrame or a
//! file, all read by the library's own reader), a probe's and observation files, every kind
//! through the command line's one observation calibration
//! ([`robocal::pipeline::calibrate_files`]), with its options and its report.

use crate::errors::{self, Kind, Place};
use crate::model::Model;
use nalgebra::Vector3;
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use robocal::calibration::kinds::{KindData, KindOptions, RowSigmaDefaults, Score};
use robocal::calibration::prior_scale::AutoPrior;
use robocal::calibration::selection::{Criterion, DEFAULT_FOLDS};
use robocal::calibration::{Choices, DataKind, Gauge, JointParams, Kinds, Loss, ParamWords};
use robocal::estimation::{Estimator, PriorEntry, RefineOptions};
use robocal::model::{Joint, JointKind, RobotModel};
use robocal::report::observations::ObservationsReport;
use robocal::table::Units;
use std::path::Path;

/// A data set: its name (a file's path, `arrays`) and a file to read or CSV text.
pub(crate) type Source = (String, Option<String>, Option<String>);

/// The text of a source: the file's or its own.
pub(crate) fn text_of(source: &Source) -> PyResult<String> {
    match source {
        (_, Some(path), _) => std::fs::read_to_string(path).map_err(|e| {
            errors::raise(
                Kind::Input,
                format!("{path}: cannot read: {e}"),
                Place { file: Some(path.clone()), ..Place::default() },
            )
        }),
        (_, None, Some(text)) => Ok(text.clone()),
        (name, None, None) => Err(errors::input(format!("{name}: neither a file nor a table"))),
    }
}

/// The units to read `source` in: a table made in memory with its own units line (an
/// observation object's) keeps them; files and DataFrames take the `given` ones (else their
/// own line's).
pub(crate) fn units_for(source: &Source, given: Option<Units>) -> Option<Units> {
    match source {
        (_, None, Some(text)) if text.starts_with("# units:") => None,
        _ => given,
    }
}

/// A data error of `source` as an input error naming the file (or the table) and the line.
pub(crate) fn data_error(source: &Source, e: &robocal::table::DataError) -> PyErr {
    errors::from_error(Kind::Input, e, Some(&source.0))
}

/// What the data holds, from its header: `markers`, `observations` or `tree-views`.
#[pyfunction]
pub fn data_kind(source: Source) -> PyResult<&'static str> {
    let text = text_of(&source)?;
    let kind = DataKind::of_csv_str(&text).map_err(|e| data_error(&source, &e))?;
    Ok(match kind {
        DataKind::Markers => "markers",
        DataKind::Observations => "observations",
        _ => "tree-views",
    })
}

/// The CSV text of marker data given as arrays, for the library's reader: a header of the
/// joint names, `x1,y1,z1`, ..., `sigma`, `qw,qx,qy,qz`, then one row per pose, each number
/// written exactly (shortest round trip).
#[pyfunction]
#[pyo3(signature = (model, joints, markers, sigma=None, orientations=None))]
pub fn measurements_csv(
    model: &Model,
    joints: PyReadonlyArray2<'_, f64>,
    markers: PyReadonlyArray2<'_, f64>,
    sigma: Option<PyReadonlyArray1<'_, f64>>,
    orientations: Option<PyReadonlyArray2<'_, f64>>,
) -> PyResult<String> {
    let (joints, markers) = (joints.as_array(), markers.as_array());
    let n = joints.nrows();
    if joints.ncols() != model.inner.dof() {
        return Err(errors::argument(
            "joints",
            format!(
                "{} columns for the {} joints of {}",
                joints.ncols(),
                model.inner.dof(),
                model.inner.name
            ),
        ));
    }
    if markers.nrows() != n || markers.ncols() == 0 || markers.ncols() % 3 != 0 {
        return Err(errors::argument(
            "markers",
            format!(
                "expected {n} rows (one per pose) of x, y, z per marker, got {} x {}",
                markers.nrows(),
                markers.ncols()
            ),
        ));
    }
    let sigma = sigma.as_ref().map(|s| s.as_array());
    let orientations = orientations.as_ref().map(|o| o.as_array());
    if sigma.as_ref().is_some_and(|s| s.len() != n) {
        return Err(errors::argument("sigma", format!("expected {n} values, one per pose")));
    }
    if orientations.as_ref().is_some_and(|o| o.nrows() != n || o.ncols() != 4) {
        return Err(errors::argument("orientations", format!("expected {n} rows of qw, qx, qy, qz")));
    }
    let mut header: Vec<String> = model.inner.joints.iter().map(|j| j.name.clone()).collect();
    header
        .extend((1..=markers.ncols() / 3).flat_map(|k| [format!("x{k}"), format!("y{k}"), format!("z{k}")]));
    if sigma.is_some() {
        header.push("sigma".into());
    }
    if orientations.is_some() {
        header.extend(["qw", "qx", "qy", "qz"].map(String::from));
    }
    let mut text = header.join(",") + "\n";
    for i in 0..n {
        let mut row: Vec<f64> = joints.row(i).to_vec();
        row.extend(markers.row(i).iter());
        row.extend(sigma.as_ref().map(|s| s[i]));
        if let Some(o) = &orientations {
            row.extend(o.row(i).iter());
        }
        let cells: Vec<String> = row.iter().map(f64::to_string).collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    Ok(text)
}

/// The CSV text of a table of observations given as columns, for the library's reader:
/// `units_line` (`# units: ...`), a header of `names` then of the `constant` columns' names,
/// then one row per value of the columns (all of one length), each number written exactly
/// (shortest round trip), a NaN as an empty cell (not measured), the constant columns' text
/// on every row.
#[pyfunction]
pub fn table_csv(
    units_line: &str,
    names: Vec<String>,
    columns: Vec<PyReadonlyArray1<'_, f64>>,
    constant: Vec<(String, String)>,
) -> PyResult<String> {
    let columns: Vec<_> = columns.iter().map(|c| c.as_array()).collect();
    let n = columns.first().map_or(0, |c| c.len());
    if names.len() != columns.len() {
        return Err(errors::input(format!("{} names for {} columns", names.len(), columns.len())));
    }
    if let Some((name, c)) = names.iter().zip(&columns).find(|(_, c)| c.len() != n) {
        return Err(errors::argument(name, format!("{} values, expected {n} (one per row)", c.len())));
    }
    let header: Vec<&str> = names.iter().chain(constant.iter().map(|c| &c.0)).map(String::as_str).collect();
    let mut text = format!("{units_line}\n{}\n", header.join(","));
    for i in 0..n {
        let cells = columns.iter().map(|c| if c[i].is_nan() { String::new() } else { c[i].to_string() });
        let cells: Vec<String> = cells.chain(constant.iter().map(|c| c.1.clone())).collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    Ok(text)
}

/// The options of `robocal.calibrate`, as the command line's flags give them.
#[derive(Debug, Clone, Default, FromPyObject)]
#[pyo3(from_item_all)]
pub struct Flags {
    pub(crate) joint_unit: Option<String>,
    pub(crate) length_unit: Option<String>,
    pub(crate) estimator: Option<String>,
    pub(crate) joint_sigma: Option<Vec<f64>>,
    pub(crate) sigma: Option<f64>,
    pub(crate) sigma_orientation: Option<f64>,
    pub(crate) noise: Option<String>,
    pub(crate) params: Vec<String>,
    pub(crate) hold: Vec<String>,
    pub(crate) keep: Vec<String>,
    pub(crate) per_session: Vec<String>,
    pub(crate) select: Option<String>,
    pub(crate) prior: Vec<String>,
    pub(crate) loss: Option<String>,
    pub(crate) folds: Option<usize>,
    pub(crate) fixed_base: bool,
    pub(crate) fixed_markers: bool,
    pub(crate) fixed_tool: bool,
    pub(crate) marker: Vec<[f64; 3]>,
    pub(crate) tool: Option<[f64; 3]>,
    pub(crate) markers: Option<Vec<usize>>,
    pub(crate) iterations: usize,
}

/// The flags made into the library's values, every rule between them checked.
pub(crate) struct Request {
    pub(crate) units: Option<Units>,
    pub(crate) noise_units: Units,
    pub(crate) estimator: Option<Estimator>,
    pub(crate) feasible: bool,
    pub(crate) joints: JointParams,
    pub(crate) prior: Vec<PriorEntry>,
    pub(crate) auto_prior: Option<AutoPrior>,
    pub(crate) loss: Loss,
    pub(crate) select: Option<Criterion>,
}

/// `Err(InputError)` about `field` unless `ok`.
pub(crate) fn require(ok: bool, field: &str, message: &str) -> PyResult<()> {
    if ok { Ok(()) } else { Err(errors::argument(field, message)) }
}

impl Flags {
    /// The flags of the units `joint_unit` and `length_unit` alone.
    pub(crate) fn with_units(joint_unit: Option<String>, length_unit: Option<String>) -> Self {
        Self { joint_unit, length_unit, ..Self::default() }
    }

    /// The units of the data (if given) and of the options (rad and m unless given).
    pub(crate) fn units(&self) -> PyResult<(Option<Units>, Units)> {
        let joint = match self.joint_unit.as_deref() {
            None => None,
            Some("rad") => Some(false),
            Some("deg") => Some(true),
            Some(other) => {
                return Err(errors::argument("joint_unit", format!("`{other}`: expected rad or deg")));
            }
        };
        let length = match self.length_unit.as_deref() {
            None => None,
            Some("m") => Some(true),
            Some("mm") => Some(false),
            Some(other) => {
                return Err(errors::argument("length_unit", format!("`{other}`: expected m or mm")));
            }
        };
        let given = match (joint, length) {
            (None, None) => None,
            (Some(j), Some(l)) => Some(Units { joints_in_degrees: j, lengths_in_metres: l }),
            _ => return Err(errors::argument("joint_unit", "joint_unit and length_unit go together")),
        };
        Ok((given, given.unwrap_or(Units { joints_in_degrees: false, lengths_in_metres: true })))
    }

    /// The request, or the first rule the flags break (the command line's rules).
    pub(crate) fn request(&self) -> PyResult<Request> {
        let (units, noise_units) = self.units()?;
        let noise = self.joint_sigma.is_some() || self.noise.is_some();
        require(
            !(self.joint_sigma.is_some() && self.noise.is_some()),
            "noise",
            "give noise or joint_sigma, not both",
        )?;
        let measurement = self.measurement_sigmas();
        require(
            !(measurement && self.noise.is_some()),
            if self.sigma.is_some() { "sigma" } else { "sigma_orientation" },
            "noise gives the measurement noise too: do not give sigma or sigma_orientation with it",
        )?;
        self.check_sigmas()?;
        let feasible = self.estimator.as_deref() == Some("fgls");
        let estimator = match self.estimator.as_deref() {
            Some("fgls") => {
                require(!noise, "estimator", "fgls estimates the noise: do not give noise or joint_sigma")?;
                require(self.folds.is_none(), "folds", "not with estimator fgls")?;
                require(self.prior.is_empty(), "prior", "not with estimator fgls")?;
                None
            }
            Some(name) => Some(name.parse::<Estimator>().map_err(|e| errors::argument("estimator", e))?),
            None => None,
        };
        let words = self.params_words()?;
        require(
            words != ParamWords::All || !(self.fixed_base || self.fixed_markers),
            "params",
            "all frees the base and the markers",
        )?;
        let joints = words.joint_params();
        // As repeated --prior: the entries in order, and `auto` at most once.
        let (mut prior, mut auto_prior) = (Vec::new(), None);
        for text in &self.prior {
            match AutoPrior::parse(text) {
                Some(_) if auto_prior.is_some() => {
                    return Err(errors::argument("prior", "auto: give it once"));
                }
                Some(auto) => auto_prior = Some(auto.map_err(|e| errors::argument("prior", e))?),
                None => prior.extend(PriorEntry::parse_list(text).map_err(|e| errors::argument("prior", e))?),
            }
        }
        let loss = match &self.loss {
            Some(text) => text.parse::<Loss>().map_err(|e| errors::argument("loss", e))?,
            None => Loss::Squared,
        };
        require(
            !feasible || loss == Loss::Squared,
            "loss",
            "a robust loss with estimator fgls: not supported; estimate the noise first (fgls reports it) and \
             give it with noise or joint_sigma",
        )?;
        let select = match self.select.as_deref() {
            None => None,
            Some("cv") => Some(Criterion::Cv { folds: self.folds.unwrap_or(DEFAULT_FOLDS) }),
            Some("bic") => Some(Criterion::Bic),
            Some("t") => Some(Criterion::T),
            Some(other) => {
                return Err(errors::argument("select", format!("`{other}`: expected cv, bic or t")));
            }
        };
        require(select.is_none() || !feasible, "select", "not with estimator fgls")?;
        require(select.is_none() || joints != JointParams::None, "select", "not with params none")?;
        if let Some(name) = self.hold.iter().find(|h| self.keep.contains(h)) {
            return Err(errors::argument("hold", format!("`{name}` is given to both hold and keep")));
        }
        require(self.folds.is_none_or(|k| k >= 2), "folds", "expected at least 2")?;
        if !(1..=robocal::limits::MAX_ITERATIONS).contains(&self.iterations) {
            let message = format!("expected a whole number from 1 to {}", robocal::limits::MAX_ITERATIONS);
            return Err(errors::argument("iterations", message));
        }
        Ok(Request { units, noise_units, estimator, feasible, joints, prior, auto_prior, loss, select })
    }

    /// `params` as the command line's `--params` reads it ([`ParamWords::parse`]): a list is
    /// its entries joined by commas, each entry a set's word or comma-separated names.
    pub(crate) fn params_words(&self) -> PyResult<ParamWords> {
        ParamWords::parse(&self.params.join(",")).map_err(|e| errors::argument("params", e))
    }

    /// Whether a measurement sigma is given (`sigma`, `sigma_orientation`): a zero one is
    /// none, as the command's default `--sigma-mm 0` is.
    pub(crate) fn measurement_sigmas(&self) -> bool {
        let given = |s: Option<f64>| s.is_some_and(|s| s != 0.0);
        given(self.sigma) || given(self.sigma_orientation)
    }

    /// Every standard deviation given a finite number from 0 to the bound of its unit (the
    /// command line's): a negative one would be squared into a valid variance unnoticed.
    fn check_sigmas(&self) -> PyResult<()> {
        use robocal::limits::{MAX_ANGLE_DEG, MAX_LENGTH_MM};
        let given = (self.joint_sigma.iter().flatten().map(|&s| ("joint_sigma", s, MAX_ANGLE_DEG)))
            .chain(self.sigma.map(|s| ("sigma", s, MAX_LENGTH_MM)))
            .chain(self.sigma_orientation.map(|s| ("sigma_orientation", s, MAX_ANGLE_DEG)));
        for (field, s, bound) in given {
            if !(s.is_finite() && (0.0..=bound).contains(&s)) {
                return Err(errors::argument(
                    field,
                    format!("{s}: expected a finite number from 0 to {bound:e}"),
                ));
            }
        }
        Ok(())
    }

    /// The nominal marker positions (mm).
    fn marker_mm(&self, units: Units) -> Vec<Vector3<f64>> {
        self.marker.iter().map(|m| Vector3::from(*m) * units.length_scale()).collect()
    }
}

/// One sigma per joint of the robot `name` with `joints` in `units` (the joint unit, the
/// length unit for prismatic joints), in rad and mm, from one value per joint or one for every
/// joint; the one reader of `joint_sigma` for chains and trees.
pub(crate) fn joint_sigmas(
    (name, joints): (&str, &[Joint]),
    sigmas: &[f64],
    units: Units,
) -> PyResult<Vec<f64>> {
    if sigmas.len() != 1 && sigmas.len() != joints.len() {
        let names: Vec<&str> = joints.iter().map(|j| j.name.as_str()).collect();
        return Err(errors::argument(
            "joint_sigma",
            format!(
                "{} values for the {} joints of {name} ({}): give one per joint or one for all",
                sigmas.len(),
                joints.len(),
                names.join(", ")
            ),
        ));
    }
    let sigma = |j: usize| sigmas[if sigmas.len() == 1 { 0 } else { j }];
    Ok((joints.iter().enumerate())
        .map(|(i, j)| match j.kind {
            JointKind::Revolute => units.angle(sigma(i)),
            JointKind::Prismatic => sigma(i) * units.length_scale(),
        })
        .collect())
}

/// A finished calibration: its report (text and JSON, as the command line's), its parameters,
/// their covariance, and the calibrated model.
#[pyclass(module = "robocal", frozen)]
pub struct Calibration {
    text: String,
    json: String,
    names: Vec<String>,
    values: Vec<f64>,
    std_errors: Vec<f64>,
    units: Vec<String>,
    covariance: nalgebra::DMatrix<f64>,
    covariance_names: Vec<String>,
    rank: usize,
    held: Vec<String>,
    sets: Vec<(String, Score)>,
    calibrated: Option<(Py<Model>, String)>,
    branches: Vec<(String, Py<Model>)>,
}

impl Calibration {
    /// The calibration of `report` (the command line's, text and JSON), its `estimate`'s
    /// covariance, the scored `sets` (the report's, of a chain) and the `calibrated` model (of
    /// a chain) or the calibrated `branches` by tip (of a tree).
    pub(crate) fn new(
        py: Python<'_>,
        report: &ObservationsReport,
        estimate: &robocal::estimation::LinearEstimate,
        rank: usize,
        sets: Vec<(String, Score)>,
        calibrated: Option<Model>,
        branches: Vec<(String, Model)>,
    ) -> PyResult<Self> {
        let rows = &report.parameters;
        Ok(Self {
            text: report.text(),
            json: serde_json::to_string_pretty(report).expect("a report serialises") + "\n",
            names: rows.iter().map(|p| p.name.clone()).collect(),
            values: rows.iter().map(|p| p.value).collect(),
            std_errors: rows.iter().map(|p| p.std_error).collect(),
            units: rows.iter().map(|p| p.unit.to_string()).collect(),
            covariance: estimate.covariance.clone(),
            covariance_names: estimate.names.clone(),
            rank,
            held: report.fixed.clone(),
            sets,
            calibrated: match calibrated {
                Some(m) => {
                    let toml = robocal::model::to_toml_with_markers(&m.inner, &m.markers);
                    Some((Py::new(py, m)?, toml))
                }
                None => None,
            },
            branches: (branches.into_iter())
                .map(|(tip, m)| Ok((tip, Py::new(py, m)?)))
                .collect::<PyResult<Vec<_>>>()?,
        })
    }
}

impl Calibration {
    /// The error of asking a tree's calibration for its one model.
    fn a_tree() -> PyErr {
        errors::input("a tree's calibration has a model per branch: see branches")
    }
}

/// A pose set's lines and errors (poses x stages x markers x 3, flattened to poses x
/// (stages x markers) x 3).
type PoseErrorArrays<'py> = (Bound<'py, PyArray1<usize>>, Bound<'py, PyArray3<f64>>);

/// The marker positions' errors of a scored set pose by pose, from its observations: each
/// pose's line, the markers' numbers (1, 2, ..., every one the set measures), and the errors
/// (measured minus predicted, mm) as poses x (before, after) x markers x 3, flattened
/// stage-major, NaN where a coordinate was not measured. A pose is a run of the set's marker
/// positions ([`Score::positions`]) on one line, each marker once.
fn pose_error_table(score: &Score) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
    let mut markers: Vec<usize> = score.positions.iter().map(|p| p.marker).collect();
    markers.sort_unstable();
    markers.dedup();
    let width = 2 * markers.len() * 3;
    let (mut lines, mut errors, mut seen) = (Vec::new(), Vec::new(), Vec::new());
    for p in &score.positions {
        if lines.last() != Some(&p.line) || seen.contains(&p.marker) {
            lines.push(p.line);
            errors.resize(errors.len() + width, f64::NAN);
            seen.clear();
        }
        seen.push(p.marker);
        let pose = errors.len() - width;
        let m = markers.binary_search(&p.marker).expect("among the set's markers");
        for r in &score.observations[p.index..p.index + p.coordinates] {
            let Some(axis) = ["marker x", "marker y", "marker z"].iter().position(|k| *k == r.kind) else {
                continue;
            };
            errors[pose + m * 3 + axis] = r.before;
            errors[pose + (markers.len() + m) * 3 + axis] = r.after;
        }
    }
    (lines, markers, errors)
}

#[pymethods]
impl Calibration {
    /// The report as `robocal calibrate` prints it.
    fn report(&self) -> String {
        self.text.clone()
    }

    /// The JSON report as `robocal calibrate --json` writes it.
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The identified parameters' names.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// Their estimated errors, in the report's units (deg, mm).
    #[getter]
    fn estimates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.values)
    }

    /// Their standard errors, in the report's units (deg, mm).
    #[getter]
    fn standard_errors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.std_errors)
    }

    /// Their units (`deg`, `mm`, ...).
    #[getter]
    fn units(&self) -> Vec<String> {
        self.units.clone()
    }

    /// The covariance of the estimate in the library's units (mm, rad), rows and columns as
    /// `covariance_names`.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let n = self.covariance.nrows();
        let rows: Vec<Vec<f64>> = (0..n).map(|r| self.covariance.row(r).iter().copied().collect()).collect();
        PyArray2::from_vec2(py, &rows).expect("a square matrix")
    }

    /// The names of the covariance's rows and columns.
    #[getter]
    fn covariance_names(&self) -> Vec<String> {
        self.covariance_names.clone()
    }

    /// The numerical rank of the identified system.
    #[getter]
    fn rank(&self) -> usize {
        self.rank
    }

    /// The combinations held because the poses cannot identify them.
    #[getter]
    fn held(&self) -> Vec<String> {
        self.held.clone()
    }

    /// The calibrated model (of a chain; a tree's are its `branches`).
    #[getter]
    fn model(&self, py: Python<'_>) -> PyResult<Py<Model>> {
        self.calibrated.as_ref().map(|(m, _)| m.clone_ref(py)).ok_or_else(Self::a_tree)
    }

    /// The calibrated model as TOML with its markers, as `--out-model` writes it.
    fn model_toml(&self) -> PyResult<String> {
        self.calibrated.as_ref().map(|(_, toml)| toml.clone()).ok_or_else(Self::a_tree)
    }

    /// A tree's calibrated branches, by tip link (empty for a chain).
    #[getter]
    fn branches(&self, py: Python<'_>) -> Vec<(String, Py<Model>)> {
        self.branches.iter().map(|(tip, m)| (tip.clone(), m.clone_ref(py))).collect()
    }

    /// The names of the scored sets, as the JSON report's `sets`: `training`, then each
    /// held-out set, then the held-out sets pooled (several of them) and the cross-validation
    /// (with folds); none for a tree.
    #[getter]
    fn sets(&self) -> Vec<String> {
        self.sets.iter().map(|(name, _)| name.clone()).collect()
    }

    /// The marker position errors (measured minus predicted, mm) of each pose of a set: poses x
    /// (stages (before, after) x markers) x 3, stage-major, NaN where not measured, with the
    /// poses' lines (none for a set without markers).
    #[pyo3(signature = (set="training"))]
    fn pose_errors<'py>(&self, py: Python<'py>, set: &str) -> PyResult<PoseErrorArrays<'py>> {
        let Some((_, score)) = self.sets.iter().find(|(name, _)| name == set) else {
            return Err(errors::argument("set", format!("`{set}`: expected one of {:?}", self.sets())));
        };
        let (lines, markers, flat) = pose_error_table(score);
        let errors = PyArray1::from_vec(py, flat).reshape([lines.len(), 2 * markers.len(), 3])?;
        Ok((PyArray1::from_vec(py, lines), errors))
    }

    fn __repr__(&self) -> String {
        format!("robocal.Calibration({} parameters, rank {})", self.names.len(), self.rank)
    }
}

/// Calibrate `model` on `sources` (marker data, a probe's, observation files: any mix, each a
/// session), with `validate` held out, as `robocal calibrate` does: every kind through the one
/// observation calibration ([`robocal::pipeline::calibrate_files`]).
#[pyfunction]
#[pyo3(signature = (model, sources, validate, flags))]
pub fn calibrate_source(
    py: Python<'_>,
    model: &Model,
    sources: Vec<Source>,
    validate: Vec<Source>,
    flags: Flags,
) -> PyResult<Calibration> {
    let request = flags.request()?;
    for source in &sources {
        if !matches!(data_kind(source.clone())?, "observations" | "markers") {
            return Err(errors::input(format!(
                "{}: files of marker positions or observations; views on a tree are calibrated by \
                 calibrate_tree",
                sources.iter().map(|s| s.0.as_str()).collect::<Vec<_>>().join(", ")
            )));
        }
    }
    observations(py, model, &sources, &validate, &flags, &request)
}

/// The command line's `calibrate` of marker data, a probe's and observation files, without
/// writing anything: every file read as observations, as the command reads them, fitted
/// together through [`robocal::pipeline::calibrate_files`].
fn observations(
    py: Python<'_>,
    robot: &Model,
    sources: &[Source],
    validate: &[Source],
    flags: &Flags,
    request: &Request,
) -> PyResult<Calibration> {
    let model = &robot.inner;
    let (spec, defaults) = observation_noise(model, flags, request)?;
    require(
        flags.per_session.is_empty() || sources.len() >= 2,
        "per_session",
        "one value per observation file (each file a session): give two files or more",
    )?;
    let read = |s: &Source| -> PyResult<(String, KindData)> {
        let data = observation_data(s, model, request, (spec.as_ref(), defaults))?;
        let stem =
            Path::new(&s.0).file_stem().map_or_else(|| s.0.clone(), |n| n.to_string_lossy().into_owned());
        Ok((s.0.clone(), data.named(&stem)))
    };
    let sessions: Files = sources.iter().map(read).collect::<PyResult<_>>()?;
    check_sessions(model, &sessions, flags)?;
    let held: Files = validate.iter().map(read).collect::<PyResult<_>>()?;
    let (sessions, held) = chosen_markers(sessions, held, flags.markers.as_deref())?;
    let mut options = kind_options(model, flags, request)?;
    if let Some(spec) = spec {
        // The noise file's joint noise, and its [prior] before the flags'.
        options.joint_noise = Some(spec.joint);
        options.prior = spec.prior.into_iter().chain(options.prior).collect();
    }
    // No noise at all: ordinary least squares, as the command line; a weighted one refused.
    let joint_noise = options.joint_noise.is_some();
    if !request.feasible && !sessions.iter().any(|(_, d)| d.noise_given(joint_noise)) {
        match request.estimator {
            None | Some(Estimator::Ols) => options.estimator = Estimator::Ols,
            Some(estimator) => {
                let message = format!(
                    "{estimator} needs the noise: give joint_sigma or noise (and sigma or a sigma column), or use \
                     estimator fgls"
                );
                return Err(errors::argument("estimator", message));
            }
        }
    }
    let choices = Choices::from_flags(request.auto_prior.clone(), request.select, flags.folds);
    let fitting = robocal::pipeline::Fitting::new(request.feasible, choices, flags.folds);
    let outcome = py
        .detach(|| robocal::pipeline::calibrate_files(&Kinds(model), &sessions, &held, &options, &fitting))
        .map_err(|e| errors::calibration(&e.source, &e.context))?;
    let (c, report) = (outcome.calibration, outcome.report);
    let calibrated = Model::new(c.calibrated.clone(), robot.urdf.clone()).with_markers(c.marker_positions());
    let sets = report.sets.clone();
    Calibration::new(py, &report, &c.refined.estimate, report.rank, sets, Some(calibrated), Vec::new())
}

/// The rules between the training `sessions` and the flags, as the command line's: sessions
/// of distinct names with `per_session`, no more `marker` than the files' markers, and the
/// memory the fit holds (`KindData::memory_estimate`, summed over the files) available.
fn check_sessions(model: &RobotModel, sessions: &[(String, KindData)], flags: &Flags) -> PyResult<()> {
    if !flags.per_session.is_empty() {
        let stems: Vec<&str> = sessions.iter().map(|(_, d)| d.sessions[0].0.as_str()).collect();
        let twice =
            (1..stems.len()).find_map(|k| stems[..k].iter().position(|s| *s == stems[k]).map(|f| (f, k)));
        if let Some((first, k)) = twice {
            let stem = stems[k];
            let message = format!(
                "{} and {} have one name, `{stem}`: each session's file stem (or name) names it",
                sessions[first].0, sessions[k].0
            );
            return Err(errors::argument("per_session", message));
        }
    }
    let files: Vec<&str> = sessions.iter().map(|(name, _)| name.as_str()).collect();
    let highest = sessions.iter().filter_map(|(_, d)| d.markers().last().map(|m| m + 1)).max().unwrap_or(0);
    if flags.marker.len() > highest {
        let message = format!(
            "{} marker given, the files ({}) have {highest} markers: the k-th marker is marker k of a marker file",
            flags.marker.len(),
            files.join(", ")
        );
        return Err(errors::argument("marker", message));
    }
    let params = model.params().len();
    let feasible = flags.estimator.as_deref() == Some("fgls");
    let bytes =
        sessions.iter().map(|(_, d)| d.memory_estimate(params, feasible)).fold(0, u64::saturating_add);
    let (observations, poses) =
        sessions.iter().fold((0, 0), |(o, p), (_, d)| (o + d.observations.len(), p + d.joints.len()));
    let what =
        format!("calibrating the {observations} observations at {poses} poses of {}", files.join(", "));
    robocal::io::check_memory(bytes, &what, "calibrate on fewer poses")
        .map_err(|e| errors::from_error(Kind::Input, &e, None))
}

/// Data files by name: sessions, or held-out sets.
type Files = Vec<(String, KindData)>;

/// The training and held-out files with the markers `ids` names only (numbers from 1: their
/// positions and orientations, [`KindData::with_markers`]; their other observations all kept),
/// or as they are, as the command line's `--markers`; a number no training file's marker has
/// is refused, and so is a file with markers, none of them named.
fn chosen_markers(sessions: Files, held: Files, ids: Option<&[usize]>) -> PyResult<(Files, Files)> {
    let Some(ids) = ids else { return Ok((sessions, held)) };
    let have: Vec<usize> = sessions.iter().flat_map(|(_, d)| d.markers()).map(|m| m + 1).collect();
    if let Some(id) = ids.iter().find(|id| !have.contains(id)) {
        return Err(errors::argument("use_markers", format!("{id}: no file has marker {id}")));
    }
    let only = |(name, d): (String, KindData)| match d.with_markers(ids) {
        Some(kept) => Ok((name, kept)),
        None => Err(errors::argument("use_markers", format!("{ids:?}: {name} has none of these markers"))),
    };
    let sessions = sessions.into_iter().map(only).collect::<PyResult<Files>>()?;
    Ok((sessions, held.into_iter().map(only).collect::<PyResult<Files>>()?))
}

/// Observation files' noise file, if given, and the sigmas of their rows without their own:
/// the noise file's `sigma_me_mm` and `sigma_orientation_deg`, else `sigma` and
/// `sigma_orientation` (a zero one is none, as for marker data), as the command line reads them.
fn observation_noise(
    model: &RobotModel,
    flags: &Flags,
    request: &Request,
) -> PyResult<(Option<robocal::estimation::NoiseSpec>, RowSigmaDefaults)> {
    let Some(path) = &flags.noise else {
        let defaults = RowSigmaDefaults::positive(
            flags.sigma.map(|s| s * request.noise_units.length_scale()),
            flags.sigma_orientation.map(|s| request.noise_units.angle(s)),
        );
        return Ok((None, defaults));
    };
    let spec = robocal::io::load_noise(Path::new(path), model)
        .map_err(|e| errors::from_error(Kind::Input, &e, None))?;
    let defaults = RowSigmaDefaults::of_noise(&spec);
    Ok((Some(spec), defaults))
}

/// An observation file's data read as the command line reads it: `defaults` for its rows
/// without a sigma, `spec`'s device (if any) at each point measured.
fn observation_data(
    source: &Source,
    model: &RobotModel,
    request: &Request,
    (spec, defaults): (Option<&robocal::estimation::NoiseSpec>, RowSigmaDefaults),
) -> PyResult<KindData> {
    let data =
        KindData::from_csv_str_with(&text_of(source)?, model, units_for(source, request.units), defaults)
            .map_err(|e| data_error(source, &e))?;
    match spec.and_then(|s| s.device.as_ref()) {
        Some(device) => data.with_device(|p| device.covariance(p)).map_err(|e| data_error(source, &e)),
        None => Ok(data),
    }
}

/// The model scored as it stands on `source`, as `robocal evaluate` scores it: through the
/// one observation pipeline ([`KindOptions::as_it_stands`]), marker data with the model's base
/// and markers, other files with their set-up fitted, the robot held; whitened by the file's
/// sigma column (or the noise's for rows without) and the joint noise. The JSON of its score.
#[pyfunction]
pub fn evaluate(model: &Model, source: Source, flags: Flags) -> PyResult<String> {
    let request = flags.request()?;
    let robot = &model.inner;
    if data_kind(source.clone())? == "tree-views" {
        return Err(errors::input(format!(
            "{}: views on a tree are not evaluated from Python yet",
            source.0
        )));
    }
    let (spec, defaults) = observation_noise(robot, &flags, &request)?;
    let mut data = observation_data(&source, robot, &request, (spec.as_ref(), defaults))?;
    if let Some(ids) = &flags.markers {
        data = data.with_markers(ids).ok_or_else(|| {
            let have: Vec<usize> = data.markers().iter().map(|m| m + 1).collect();
            errors::argument("markers", format!("{ids:?}: {} has markers {have:?}", source.0))
        })?;
    }
    let joint_noise = match spec {
        Some(spec) => Some(spec.joint),
        None => kind_options(robot, &flags, &request)?.joint_noise,
    };
    let options = KindOptions::as_it_stands(robot, &model.markers, &data)
        .map_err(|e| errors::calibration(&e, &source.0))?;
    let options = KindOptions { joint_noise, ..options };
    let score = robocal::calibration::kinds::evaluate_kinds(robot, &data, &options)
        .map_err(|e| errors::calibration(&e, &source.0))?;
    Ok(serde_json::to_string(&score).expect("a score serialises"))
}

/// The library's options for observation files: the joint noise (`Sigma_q`, rad² and mm²),
/// the estimator (wls unless told), the parameters, the tool point and the markers.
fn kind_options(model: &RobotModel, flags: &Flags, request: &Request) -> PyResult<KindOptions> {
    let joint_noise = match &flags.joint_sigma {
        Some(sigmas) => {
            let sigmas = joint_sigmas((&model.name, &model.joints), sigmas, request.noise_units)?;
            Some(nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
                sigmas.len(),
                sigmas.iter().map(|s| s * s),
            )))
        }
        None => None,
    };
    Ok(KindOptions {
        per_session: flags.per_session.clone(),
        prior: request.prior.clone(),
        loss: request.loss,
        gauge: Gauge { hold: flags.hold.clone(), keep: flags.keep.clone() },
        estimator: request.estimator.unwrap_or(Estimator::Wls),
        joint_noise,
        joints: request.joints.clone(),
        estimate_tool: !flags.fixed_tool,
        estimate_base: !flags.fixed_base,
        estimate_markers: !flags.fixed_markers,
        tool: flags.tool.map_or_else(
            || model.tool_point_in_marker_frame(),
            |t| Vector3::from(t) * request.noise_units.length_scale(),
        ),
        markers: flags.marker_mm(request.noise_units),
        probe: None,
        refine: RefineOptions { max_iterations: flags.iterations, ..RefineOptions::default() },
    })
}
