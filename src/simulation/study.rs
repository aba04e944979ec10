//! The study file (TOML): a calibration campaign to simulate, as data.

use crate::design::Criterion;
use crate::error::FieldError;
use crate::estimation::{Device, DeviceTable, Estimator};
use crate::kinematics::Measured;
use crate::limits::{
    MAX_ANGLE_DEG, MAX_CANDIDATES, MAX_CASES, MAX_COMPLIANCE, MAX_ITERATIONS, MAX_LENGTH_MM, MAX_MASS_KG,
    MAX_PLAY, MAX_POINTS, MAX_RUNS, MAX_RUNS_PER_CASE, MAX_STUDY_WORK, MAX_TEST_POINTS, MIN_SIGMA,
    check_magnitude, check_range, shown,
};
use crate::model::{JointKind, ModelRef, ParamKind, Payload, RobotModel, Selection, SelectionError, degrees};
use serde::Deserialize;

/// Why a study file could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StudyError {
    /// Not valid TOML, or missing, misspelled or mistyped fields (the source names the line).
    #[error("the study file has a mistake")]
    Syntax(#[source] toml::de::Error),
    /// A field with a value that makes no study.
    #[error(transparent)]
    Invalid(#[from] FieldError),
    /// The robot could not be loaded (the source says why).
    #[error("field `robot`")]
    Robot(#[source] Box<dyn std::error::Error + Send + Sync>),
}

/// When the "real" robot's geometric errors are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Redraw {
    /// A new real robot every run.
    Run,
    /// One real robot per point set, shared by its runs.
    Set,
}

/// Standard deviations of the real robot's geometric errors (normal, zero mean), drawn for the
/// identified parameters only: the others are exact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSizes {
    /// Revolute joint offsets (rad).
    pub offset: f64,
    /// Every other angle: alpha, beta, revolute-joint-free rotations of base and tool (rad).
    pub angle: f64,
    /// Every length: d, a, base and tool translations, prismatic offsets (mm).
    pub length: f64,
    /// When they are drawn.
    pub redraw: Redraw,
}

/// One case of a study: how many points, how much measurement noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case {
    /// Measurement points `N_p`.
    pub points: usize,
    /// Measurement noise `sigma_me` (mm), isotropic.
    pub sigma_me: f64,
    /// How the points are chosen.
    pub poses: PoseChoice,
}

/// How the measurement points of a case are chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseChoice {
    /// Uniform within the joint limits: the paper's step 1.
    Random,
    /// Planned ([`crate::design::Design::plan`]) on the whitened `H` of the study's noise
    /// model, from the random set of the same case and set plus further uniform candidates,
    /// `candidates` in all.
    Planned {
        /// What the plan maximises.
        criterion: Criterion,
        /// Size of the candidate pool.
        candidates: usize,
    },
}

impl PoseChoice {
    /// `random` or `planned`, as in the study file.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Random => "random",
            Self::Planned { .. } => "planned",
        }
    }
}

/// One calibration a study compares: an estimator identifying the study's parameters and,
/// beyond the paper, the joints' responses to their gravity load: `wls+compliance` adds every
/// joint's compliance (`<joint>.compliance`), `+play` every joint's play, so that a study can
/// show what modelling them gains over the geometric model on the same runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Compared {
    /// The estimator.
    pub estimator: Estimator,
    /// Whether the compliances are identified too.
    pub compliance: bool,
    /// Whether the plays are identified too.
    pub play: bool,
}

impl From<Estimator> for Compared {
    fn from(estimator: Estimator) -> Self {
        Self { estimator, compliance: false, play: false }
    }
}

impl std::fmt::Display for Compared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.estimator.name())?;
        if self.compliance {
            f.write_str("+compliance")?;
        }
        if self.play {
            f.write_str("+play")?;
        }
        Ok(())
    }
}

impl std::str::FromStr for Compared {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let mut parts = s.split('+');
        let mut compared = Compared::from(parts.next().unwrap_or_default().parse::<Estimator>()?);
        for part in parts {
            match part {
                "compliance" if !compared.compliance => compared.compliance = true,
                "play" if !compared.play => compared.play = true,
                other => {
                    return Err(format!(
                        "`{s}`: after the estimator, `+compliance` and `+play` (each once), found `+{other}`"
                    ));
                }
            }
        }
        Ok(compared)
    }
}

impl Compared {
    /// The parameters this calibration identifies: the study's `selection` and, as asked, the
    /// compliances and plays of `robot` (a model with masses has them).
    pub fn selection(&self, robot: &RobotModel, selection: &Selection) -> Selection {
        let params = robot.params();
        let extra = (0..params.len()).filter(|&i| match params.get(i).kind {
            ParamKind::Compliance => self.compliance,
            ParamKind::Play => self.play,
            _ => false,
        });
        Selection::from_indices(&params, selection.indices().iter().copied().chain(extra))
    }
}

/// The real robot's responses to its gravity load, beyond its geometric errors: what a
/// geometric calibration cannot express.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrueLoads {
    /// Each joint's compliance (rad/N·m; mm/N for a prismatic joint).
    pub compliance: Vec<f64>,
    /// Each joint's play (rad; mm for a prismatic joint).
    pub play: Vec<f64>,
}

/// A published result to print beside ours: one row of the paper's tables.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reference {
    /// `N_p` of the row.
    pub points: usize,
    /// `sigma_me` (mm) of the row.
    pub sigma_me_mm: f64,
    /// Mean dE (%).
    pub mean: f64,
    /// Standard deviation of dE (%).
    pub sd: f64,
    /// Lowest dE (%).
    pub lowest: f64,
    /// Highest dE (%).
    pub highest: f64,
    /// Share of runs with dE > 0 (%).
    pub above_zero: f64,
}

/// A validated study: everything a simulation needs, in mm and rad. Its fields are public, to
/// be read and adjusted ([`Study::set_noise`] and the like); [`crate::simulation::run`] checks
/// them again ([`Study::check`]) before it runs.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// Short name, used in file names.
    pub name: String,
    /// What the study shows.
    pub description: String,
    /// The nominal robot.
    pub robot: RobotModel,
    /// Position or pose measurements.
    pub measured: Measured,
    /// The identified parameters.
    pub selection: Selection,
    /// Joint noise standard deviations (rad, mm for prismatic joints).
    pub joint_sigmas: Vec<f64>,
    /// Orientation measurement noise (rad), for pose measurements.
    pub sigma_orientation: f64,
    /// The measuring device, if any: its covariance at each point, plus `sigma_me^2 I` of the
    /// case, is the measurement noise (simulated and in `V_k`).
    pub device: Option<Device>,
    /// The real robot's geometric errors.
    pub errors: ErrorSizes,
    /// The cases: every `N_p` with every `sigma_me`.
    pub cases: Vec<Case>,
    /// Point sets per case.
    pub point_sets: usize,
    /// Runs per point set.
    pub runs_per_set: usize,
    /// Configurations in the test set that measures the calibrated accuracy.
    pub test_points: usize,
    /// The calibrations compared; the first is the baseline of dE.
    pub estimators: Vec<Compared>,
    /// The real robot's compliances and plays (zero: a rigid robot, the paper's). A payload
    /// (`[truth] payload_kg`) is part of [`Study::robot`]'s masses: known to the calibration.
    pub truth: TrueLoads,
    /// Linear steps per estimate: 1 is the paper's one-step estimate.
    pub iterations: usize,
    /// Master seed of every random stream.
    pub seed: u64,
    /// Published values to print beside ours.
    pub reference: Vec<Reference>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    name: String,
    #[serde(default)]
    description: String,
    robot: String,
    #[serde(default)]
    base_link: Option<String>,
    #[serde(default)]
    tip_link: Option<String>,
    measured: MeasuredName,
    parameters: Parameters,
    estimators: Vec<String>,
    #[serde(default = "one")]
    iterations: usize,
    seed: u64,
    point_sets: usize,
    runs_per_set: usize,
    test_points: usize,
    noise: NoiseFile,
    errors: ErrorsFile,
    cases: CasesFile,
    #[serde(default)]
    reference: Vec<Reference>,
    #[serde(default)]
    design: Option<DesignFile>,
    #[serde(default)]
    truth: Option<TruthFile>,
}

/// `[truth]`: the real robot's responses to gravity, and the payload it carries.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TruthFile {
    /// Compliance by joint name: rad/N·m (mm/N for a prismatic joint).
    #[serde(default)]
    compliance: std::collections::BTreeMap<String, f64>,
    /// Play by joint name: degrees (mm for a prismatic joint).
    #[serde(default)]
    play: std::collections::BTreeMap<String, f64>,
    /// The payload's mass (kg), known to the calibration.
    #[serde(default)]
    payload_kg: f64,
    /// Its centre of mass in the tip frame (mm).
    #[serde(default)]
    payload_com_mm: [f64; 3],
}

/// `[design]`: the pose choices every case is run with.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DesignFile {
    poses: Vec<String>,
    #[serde(default = "d_optimal")]
    criterion: String,
    #[serde(default = "default_candidates")]
    candidates: usize,
}

fn d_optimal() -> String {
    "d".into()
}

fn default_candidates() -> usize {
    2000
}

fn one() -> usize {
    1
}

#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
enum MeasuredName {
    Position,
    Pose,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum Parameters {
    Named(String),
    List(Vec<String>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoiseFile {
    /// One per joint: degrees for revolute joints, mm for prismatic ones.
    joint_sigma: Vec<f64>,
    #[serde(default)]
    sigma_orientation_deg: f64,
    /// The measuring device (`[noise.device]`, the table of a noise file).
    device: Option<DeviceTable>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ErrorsFile {
    offset_deg: f64,
    angle_deg: f64,
    length_mm: f64,
    redraw: Redraw,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CasesFile {
    points: Vec<usize>,
    sigma_me_mm: Vec<f64>,
}

impl Study {
    /// Read a study from TOML text; `load_robot` turns the `robot` field (a preset name, a
    /// model file, or a URDF file with the optional `base_link` and `tip_link`) into a model.
    /// See `docs/formats.md` for the fields.
    pub fn from_toml_str<E: Into<Box<dyn std::error::Error + Send + Sync>>>(
        text: &str,
        load_robot: impl FnOnce(&ModelRef) -> Result<RobotModel, E>,
    ) -> Result<Self, StudyError> {
        let file: StudyFile = toml::from_str(text).map_err(StudyError::Syntax)?;
        let reference = model_ref(&file)?;
        let robot = load_robot(&reference).map_err(|e| StudyError::Robot(e.into()))?;
        let (robot, truth) = truth(robot, file.truth.as_ref())?;
        let selection = selection(&robot, &file.parameters)?;
        let estimators = estimators(&file.estimators)?;
        let joint_sigmas = joint_sigmas(&robot, &file.noise.joint_sigma)?;
        if file.cases.points.is_empty() || file.cases.sigma_me_mm.is_empty() {
            let expected = "at least one value in `points` and in `sigma_me_mm`";
            return Err(FieldError::new("cases", expected).into());
        }
        let device = match &file.noise.device {
            Some(table) => Some(table.device("noise.device.")?),
            None => None,
        };
        let cases = cases(&file.cases, file.design.as_ref())?;
        let study = Self {
            name: file.name,
            description: file.description,
            measured: match file.measured {
                MeasuredName::Position => Measured::Position,
                MeasuredName::Pose => Measured::Pose,
            },
            selection,
            joint_sigmas,
            sigma_orientation: file.noise.sigma_orientation_deg.to_radians(),
            device,
            errors: ErrorSizes {
                offset: file.errors.offset_deg.to_radians(),
                angle: file.errors.angle_deg.to_radians(),
                length: file.errors.length_mm,
                redraw: file.errors.redraw,
            },
            cases,
            point_sets: file.point_sets,
            runs_per_set: file.runs_per_set,
            test_points: file.test_points,
            estimators,
            truth,
            iterations: file.iterations,
            seed: file.seed,
            reference: file.reference,
            robot,
        };
        study.check()?;
        Ok(study)
    }

    /// Check that the study's values make a study: a name fit for file names, at least one
    /// parameter, two estimators, one finite joint sigma >= 0 per joint, finite error sizes
    /// and noise >= 0, every magnitude and count within its bound in [`crate::limits`] (points,
    /// sets, runs, test points, iterations, the runs and the work of the whole study), at
    /// least 2 runs per case. Errors name the study file's field.
    pub fn check(&self) -> Result<(), StudyError> {
        check_name(&self.name)?;
        self.check_estimators()?;
        self.check_truth()?;
        check_joint_count(&self.robot, self.joint_sigmas.len())?;
        self.check_noise_non_negative()?;
        self.check_magnitudes()?;
        self.check_sigmas()?;
        self.check_counts()?;
        self.check_cases()?;
        self.check_work()
    }

    /// At least one parameter, at least two estimators, and a robot with masses for an
    /// estimator that identifies compliances or plays.
    fn check_estimators(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        if self.selection.is_empty() {
            return invalid("parameters", "at least one parameter".into());
        }
        if self.estimators.len() < 2 {
            return invalid(
                "estimators",
                "at least two, the first the baseline of dE (e.g. [\"ols\", \"wls\"])".into(),
            );
        }
        let masses = self.robot.has_masses();
        if let Some(c) = self.estimators.iter().find(|c| (c.compliance || c.play) && !masses) {
            return invalid(
                "estimators",
                format!(
                    "a robot with masses for `{c}` (a model's [[links]], a URDF's <inertial>, or a payload)"
                ),
            );
        }
        Ok(())
    }

    /// The true compliances and plays: none, or one finite value per joint; not zero only on
    /// a robot with masses, for gravity to load its joints.
    fn check_truth(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        let (masses, dof) = (self.robot.has_masses(), self.robot.dof());
        for (field, values) in
            [("truth.compliance", &self.truth.compliance), ("truth.play", &self.truth.play)]
        {
            if !(values.is_empty() || values.len() == dof && values.iter().all(|v| v.is_finite())) {
                return invalid(field, format!("a finite value per joint of {}", self.robot.name));
            }
            if values.iter().any(|&v| v != 0.0) && !masses {
                return invalid(field, "a robot with masses, for gravity to load its joints".into());
            }
        }
        Ok(())
    }

    /// Every noise and error size finite >= 0 in its file's unit, field by field (a field of
    /// several values by its smallest, or NaN: [`min_or_nan`]).
    fn check_noise_non_negative(&self) -> Result<(), StudyError> {
        let sigma_me = self.cases.iter().map(|c| c.sigma_me);
        // (field, smallest value, in the file's unit)
        let joint_sigma = self.robot.joints.iter().zip(&self.joint_sigmas).map(|(j, &s)| match j.kind {
            JointKind::Revolute => degrees(s),
            JointKind::Prismatic => s,
        });
        let non_negative = [
            ("noise.joint_sigma", joint_sigma.fold(0.0, min_or_nan)),
            ("noise.sigma_orientation_deg", degrees(self.sigma_orientation)),
            ("errors.offset_deg", degrees(self.errors.offset)),
            ("errors.angle_deg", degrees(self.errors.angle)),
            ("errors.length_mm", self.errors.length),
            ("cases.sigma_me_mm", sigma_me.fold(0.0, min_or_nan)),
        ];
        for (field, value) in non_negative {
            check_non_negative(field, value)?;
        }
        Ok(())
    }

    /// Every noise and error size within [`MAX_ANGLE_DEG`] or [`MAX_LENGTH_MM`] in its file's
    /// unit, and the joint sigmas and `sigma_me` finite.
    fn check_magnitudes(&self) -> Result<(), StudyError> {
        let joint_sigma = self.robot.joints.iter().zip(&self.joint_sigmas).map(|(j, &s)| match j.kind {
            JointKind::Revolute => ("noise.joint_sigma", degrees(s), MAX_ANGLE_DEG, "deg"),
            JointKind::Prismatic => ("noise.joint_sigma", s, MAX_LENGTH_MM, "mm"),
        });
        let magnitudes = joint_sigma
            .chain(self.cases.iter().map(|c| ("cases.sigma_me_mm", c.sigma_me, MAX_LENGTH_MM, "mm")))
            .chain([
                ("noise.sigma_orientation_deg", degrees(self.sigma_orientation), MAX_ANGLE_DEG, "deg"),
                ("errors.offset_deg", degrees(self.errors.offset), MAX_ANGLE_DEG, "deg"),
                ("errors.angle_deg", degrees(self.errors.angle), MAX_ANGLE_DEG, "deg"),
                ("errors.length_mm", self.errors.length, MAX_LENGTH_MM, "mm"),
            ]);
        for (field, value, bound, unit) in magnitudes {
            check_magnitude(value, bound, unit).map_err(|e| FieldError::new(field, e))?;
        }
        let all_finite =
            self.joint_sigmas.iter().chain(self.cases.iter().map(|c| &c.sigma_me)).all(|v| v.is_finite());
        if !all_finite {
            return Err(FieldError::new("noise.joint_sigma / cases.sigma_me_mm", "finite values").into());
        }
        Ok(())
    }

    /// Point sets, runs per set, test points and iterations from 1 to their bounds in
    /// [`crate::limits`], and at least 2 runs per case, `point_sets x runs_per_set`.
    fn check_counts(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        for (field, count, bound) in [
            ("point_sets", self.point_sets, MAX_RUNS_PER_CASE),
            ("runs_per_set", self.runs_per_set, MAX_RUNS_PER_CASE),
            ("test_points", self.test_points, MAX_TEST_POINTS),
            ("iterations", self.iterations, MAX_ITERATIONS),
        ] {
            if count == 0 {
                return invalid(field, "at least 1".into());
            }
            if count > bound {
                return invalid(field, format!("at most {bound}, found {count}"));
            }
        }
        if self.point_sets.saturating_mul(self.runs_per_set) < 2 {
            return invalid(
                "runs_per_set",
                "at least 2 runs per case (point_sets x runs_per_set) for a spread".into(),
            );
        }
        Ok(())
    }

    /// At least one case, each of 1 to [`MAX_POINTS`] points.
    fn check_cases(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        if self.cases.is_empty() {
            return invalid("cases", "at least one value in `points` and in `sigma_me_mm`".into());
        }
        if let Some(case) = self.cases.iter().find(|c| c.points == 0 || c.points > MAX_POINTS) {
            return invalid(
                "cases.points",
                format!("point counts from 1 to {MAX_POINTS}, found {}", case.points),
            );
        }
        Ok(())
    }

    /// The whole study within bounds: at most [`MAX_STUDY_WORK`] kinematic evaluations
    /// ([`Study::work`]) and at most [`MAX_RUNS`] runs, `cases x point_sets x runs_per_set`.
    fn check_work(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        let work = self.work();
        if work > MAX_STUDY_WORK {
            return invalid(
                "runs_per_set",
                format!(
                    "a study of at most {MAX_STUDY_WORK:e} kinematic evaluations (runs x (points + test_points)), \
                     found {work:e}: ask for fewer runs, points or test_points"
                ),
            );
        }
        let runs = self.cases.len().saturating_mul(self.point_sets).saturating_mul(self.runs_per_set);
        if runs > MAX_RUNS {
            return invalid(
                "runs_per_set",
                format!("at most {MAX_RUNS} runs in all (cases x point_sets x runs_per_set), found {runs}"),
            );
        }
        Ok(())
    }

    /// Every standard deviation 0 (exact) or at least [`MIN_SIGMA`] in its field's unit, and a
    /// pose study's orientation noise above 0: every estimate weighs the orientation rows by it.
    fn check_sigmas(&self) -> Result<(), StudyError> {
        let joint_sigma = self.robot.joints.iter().zip(&self.joint_sigmas).map(|(j, &s)| match j.kind {
            JointKind::Revolute => ("noise.joint_sigma", degrees(s), "deg"),
            JointKind::Prismatic => ("noise.joint_sigma", s, "mm"),
        });
        let sigmas = joint_sigma
            .chain([("noise.sigma_orientation_deg", degrees(self.sigma_orientation), "deg")])
            .chain(self.cases.iter().map(|c| ("cases.sigma_me_mm", c.sigma_me, "mm")));
        for (field, value, unit) in sigmas {
            if value > 0.0 && value < MIN_SIGMA {
                let expected = format!(
                    "0 (exact) or a standard deviation of at least {MIN_SIGMA:e} {unit}, found {}",
                    shown(value)
                );
                return Err(FieldError::new(field, expected).into());
            }
        }
        if self.measured == Measured::Pose && self.sigma_orientation == 0.0 {
            let expected = "a standard deviation above 0 deg in a pose study (measured = \"pose\"), which weighs \
                            the orientation rows by it (with --noise, the noise file's sigma_orientation_deg)";
            return Err(FieldError::new("noise.sigma_orientation_deg", expected).into());
        }
        Ok(())
    }

    /// The work of the study in kinematic evaluations: the sum over its runs of the points
    /// and the test points, bounded by [`MAX_STUDY_WORK`].
    pub fn work(&self) -> u64 {
        let runs_per_case = (self.point_sets as u64).saturating_mul(self.runs_per_set as u64);
        self.cases.iter().fold(0u64, |work, case| {
            work.saturating_add(runs_per_case.saturating_mul((case.points + self.test_points) as u64))
        })
    }

    /// The memory the study will need at most, in bytes, on `threads` threads: every point
    /// set held at once (per point the joints, the nominal pose, and the `b x (p + dof)`
    /// Jacobian rows: `8 (dof + b (p + dof) + 32)` bytes), plus per thread the stacked `H`, its
    /// whitened copy, the solve's workspace and `y` (`4 x 8 N_p b p`), the planner's candidate
    /// rows (`3 x 8 b p` per candidate) and the real robot at every test point (`128 x
    /// test_points`), plus the test set (`8 dof + 152` a point) and the results (`64` bytes per
    /// run and estimator). `b` is 3 (position) or 6 (pose), `p` the identified parameters. A
    /// bound to refuse absurd studies before allocating, not an account.
    pub fn memory_estimate(&self, threads: usize) -> u64 {
        let (b, p, dof) = (self.measured.rows() as u64, self.selection.len() as u64, self.robot.dof() as u64);
        let sets: u64 = self.cases.iter().map(|c| c.points as u64 * self.point_sets as u64).sum();
        let largest = self.cases.iter().map(|c| c.points as u64).max().unwrap_or(0);
        let candidates = self
            .cases
            .iter()
            .map(|c| match c.poses {
                PoseChoice::Planned { candidates, .. } => candidates as u64,
                PoseChoice::Random => 0,
            })
            .max()
            .unwrap_or(0);
        let runs = self.cases.len() as u64 * self.point_sets as u64 * self.runs_per_set as u64;
        let per_thread = 32 * largest * b * p + 24 * candidates * b * p + 128 * self.test_points as u64;
        sets.saturating_mul(8 * (dof + b * (p + dof) + 32))
            .saturating_add((threads.max(1) as u64).saturating_mul(per_thread))
            .saturating_add(self.test_points as u64 * (8 * dof + 152))
            .saturating_add(runs.saturating_mul(64 * self.estimators.len() as u64))
    }

    /// Replace the study's noise by a noise file's: the joint sigmas, the device, the
    /// orientation noise, and, if the file gives `sigma_me_mm`, every case's `sigma_me`
    /// (the cases then are the study's `N_p` with that one value). A study simulates
    /// uncorrelated joint noise, so a full `Sigma_q` with correlations is refused.
    pub fn set_noise(&mut self, spec: &crate::estimation::NoiseSpec) -> Result<(), StudyError> {
        let dof = self.robot.dof();
        if spec.joint.shape() != (dof, dof) {
            let expected = format!("a noise file for the {dof} joints of {}", self.robot.name);
            return Err(FieldError::new("noise", expected).into());
        }
        if (0..dof).any(|i| (0..dof).any(|j| i != j && spec.joint[(i, j)] != 0.0)) {
            let expected = "per-joint sigmas: a study simulates uncorrelated joint noise";
            return Err(FieldError::new("joint_covariance", expected).into());
        }
        self.joint_sigmas = spec.joint_sigmas();
        self.device = spec.device.clone();
        self.sigma_orientation = spec.sigma_orientation;
        if let Some(sigma_me) = spec.sigma_me {
            let mut cases: Vec<Case> = Vec::new();
            for case in &self.cases {
                let case = Case { sigma_me, ..*case };
                if !cases.contains(&case) {
                    cases.push(case);
                }
            }
            self.cases = cases;
        }
        Ok(())
    }

    /// The real robot before its geometric errors: [`Study::robot`] with the true compliances
    /// and plays.
    pub fn real_robot(&self) -> RobotModel {
        let mut real = self.robot.clone();
        for (j, joint) in real.joints.iter_mut().enumerate() {
            joint.compliance += self.truth.compliance.get(j).copied().unwrap_or(0.0);
            joint.play += self.truth.play.get(j).copied().unwrap_or(0.0);
        }
        real
    }

    /// The published row for `case`, if the study has one.
    pub fn reference_for(&self, case: &Case) -> Option<&Reference> {
        self.reference.iter().find(|r| r.points == case.points && r.sigma_me_mm == case.sigma_me)
    }
}

/// The `noise.joint_sigma` of a study file (deg; mm for a prismatic joint), one per joint of
/// `robot`, in rad and mm.
pub(crate) fn joint_sigmas(robot: &RobotModel, sigmas: &[f64]) -> Result<Vec<f64>, StudyError> {
    check_joint_count(robot, sigmas.len())?;
    Ok((robot.joints.iter().zip(sigmas))
        .map(|(j, &s)| if j.kind == JointKind::Revolute { s.to_radians() } else { s })
        .collect())
}

/// The robot a study file names: its `robot` and, for a URDF robot only, its `base_link` and
/// `tip_link`.
fn model_ref(file: &StudyFile) -> Result<ModelRef, StudyError> {
    let reference = ModelRef {
        name: file.robot.clone(),
        base_link: file.base_link.clone(),
        tip_link: file.tip_link.clone(),
        payload: None,
    };
    if !reference.is_urdf() && (reference.base_link.is_some() || reference.tip_link.is_some()) {
        let expected = "only with a URDF robot (a `.urdf` file)";
        return Err(FieldError::new(
            if reference.base_link.is_some() { "base_link" } else { "tip_link" },
            expected,
        )
        .into());
    }
    Ok(reference)
}

/// The identified parameters of `robot` a study file's `parameters` names: `joints`, `all`,
/// `offsets`, or a parameter's name or a list of names.
fn selection(robot: &RobotModel, parameters: &Parameters) -> Result<Selection, StudyError> {
    let params = robot.params();
    Ok(match parameters {
        Parameters::Named(name) if name == "joints" => Selection::joints(&params),
        Parameters::Named(name) if name == "all" => Selection::all(&params),
        Parameters::Named(name) if name == "offsets" => Selection::offsets(&params),
        Parameters::Named(name) => Selection::by_names(&params, &[name]).map_err(selection_error)?,
        Parameters::List(names) => Selection::by_names(&params, names).map_err(selection_error)?,
    })
}

/// The calibrations a study file's `estimators` names, each once.
fn estimators(names: &[String]) -> Result<Vec<Compared>, StudyError> {
    let estimators: Vec<Compared> = names
        .iter()
        .map(|e| e.parse())
        .collect::<Result<_, String>>()
        .map_err(|e| FieldError::new("estimators", e))?;
    if let Some(i) = (1..estimators.len()).find(|&i| estimators[..i].contains(&estimators[i])) {
        let expected = format!("each estimator once, found {:?} twice", names[i]);
        return Err(FieldError::new("estimators", expected).into());
    }
    Ok(estimators)
}

/// The cases of `[cases]` and `[design]`: every `N_p` with every `sigma_me` and every pose
/// choice ([`pose_choices`]), in that order, at most [`MAX_CASES`] of them.
fn cases(file: &CasesFile, design: Option<&DesignFile>) -> Result<Vec<Case>, StudyError> {
    let choices = pose_choices(design, &file.points)?;
    let count = file.points.len().saturating_mul(file.sigma_me_mm.len()).saturating_mul(choices.len());
    if count > MAX_CASES {
        let expected =
            format!("at most {MAX_CASES} cases (points x sigma_me_mm x design.poses), found {count}");
        return Err(FieldError::new("cases", expected).into());
    }
    Ok(file
        .points
        .iter()
        .flat_map(|&points| file.sigma_me_mm.iter().map(move |&sigma_me| (points, sigma_me)))
        .flat_map(|(points, sigma_me)| choices.iter().map(move |&poses| Case { points, sigma_me, poses }))
        .collect())
}

/// `noise.joint_sigma` has `count` values, one per joint of `robot`.
pub(crate) fn check_joint_count(robot: &RobotModel, count: usize) -> Result<(), StudyError> {
    if count != robot.dof() {
        let expected = format!("{} values, one per joint of {}", robot.dof(), robot.name);
        return Err(FieldError::new("noise.joint_sigma", expected).into());
    }
    Ok(())
}

/// `value` of `field` is finite and `>= 0`.
pub(crate) fn check_non_negative(field: &str, value: f64) -> Result<(), StudyError> {
    if !(value >= 0.0 && value.is_finite()) {
        return Err(FieldError::new(field, format!("finite values >= 0, found {value}")).into());
    }
    Ok(())
}

/// A study's name, which names its output folder: letters, digits, `-` or `_`.
pub(crate) fn check_name(name: &str) -> Result<(), StudyError> {
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_') {
        let expected = format!("letters, digits, `-` or `_` (it names files), found {name:?}");
        return Err(FieldError::new("name", expected).into());
    }
    Ok(())
}

/// The smaller of `a` and `b`, or NaN if either is NaN (so that a NaN is found and named).
fn min_or_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() { f64::NAN } else { a.min(b) }
}

/// The pose choices of `[design]` (random only without it), validated.
fn pose_choices(design: Option<&DesignFile>, points: &[usize]) -> Result<Vec<PoseChoice>, StudyError> {
    let Some(design) = design else { return Ok(vec![PoseChoice::Random]) };
    let invalid = |field: &str, expected: String| StudyError::from(FieldError::new(field, expected));
    let criterion: Criterion = design.criterion.parse().map_err(|e| invalid("design.criterion", e))?;
    let largest = points.iter().copied().max().unwrap_or(0);
    if design.candidates < largest || design.candidates > MAX_CANDIDATES {
        return Err(invalid(
            "design.candidates",
            format!("from the largest N_p ({largest}) to {MAX_CANDIDATES}, found {}", design.candidates),
        ));
    }
    let mut choices = Vec::new();
    for name in &design.poses {
        let choice = match name.as_str() {
            "random" => PoseChoice::Random,
            "planned" => PoseChoice::Planned { criterion, candidates: design.candidates },
            other => {
                return Err(invalid("design.poses", format!("\"random\" or \"planned\", found {other:?}")));
            }
        };
        if choices.contains(&choice) {
            return Err(invalid("design.poses", format!("{name:?} given twice")));
        }
        choices.push(choice);
    }
    if choices.is_empty() {
        return Err(invalid("design.poses", "at least one of \"random\", \"planned\"".into()));
    }
    Ok(choices)
}

/// The robot carrying `[truth]`'s payload, and the true compliances and plays by joint.
fn truth(robot: RobotModel, file: Option<&TruthFile>) -> Result<(RobotModel, TrueLoads), StudyError> {
    let Some(file) = file else { return Ok((robot, TrueLoads::default())) };
    let invalid = |field: String, expected: String| StudyError::from(FieldError::new(field, expected));
    let by_joint = |field: &str, table: &std::collections::BTreeMap<String, f64>| {
        let mut values = vec![0.0; robot.dof()];
        for (name, &value) in table {
            let Some(j) = robot.joints.iter().position(|j| &j.name == name) else {
                let names: Vec<&str> = robot.joints.iter().map(|j| j.name.as_str()).collect();
                return Err(invalid(
                    format!("{field}.{name}"),
                    format!("a joint of the robot: {}", names.join(", ")),
                ));
            };
            let revolute = robot.joints[j].kind == JointKind::Revolute;
            let (low, high, unit) = match (field, revolute) {
                ("truth.compliance", true) => (0.0, MAX_COMPLIANCE, "rad/(N·m)"),
                ("truth.compliance", false) => (0.0, MAX_COMPLIANCE, "mm/N"),
                (_, true) => (-MAX_PLAY, MAX_PLAY, "deg"),
                (_, false) => (-MAX_PLAY, MAX_PLAY, "mm"),
            };
            values[j] =
                check_range(value, low, high, unit).map_err(|e| invalid(format!("{field}.{name}"), e))?;
        }
        Ok(values)
    };
    let compliance = by_joint("truth.compliance", &file.compliance)?;
    let mut play = by_joint("truth.play", &file.play)?;
    for (p, joint) in play.iter_mut().zip(&robot.joints) {
        if joint.kind == JointKind::Revolute {
            *p = p.to_radians();
        }
    }
    check_range(file.payload_kg, 0.0, MAX_MASS_KG, "kg")
        .map_err(|e| invalid("truth.payload_kg".into(), e))?;
    for &v in &file.payload_com_mm {
        check_magnitude(v, MAX_LENGTH_MM, "mm").map_err(|e| invalid("truth.payload_com_mm".into(), e))?;
    }
    let robot = if file.payload_kg > 0.0 {
        robot.with_payload(&Payload { mass: file.payload_kg, com: file.payload_com_mm.into() })
    } else {
        robot
    };
    Ok((robot, TrueLoads { compliance, play }))
}

fn selection_error(e: SelectionError) -> StudyError {
    FieldError::new("parameters", e.to_string()).into()
}

/// The studies shipped with robocal: `(name, TOML text)`. `paper-table1` and `paper-table2`
/// are the paper's two studies; `robocal reproduce` runs both. `device-cmm`,
/// `device-laser-tracker` and `device-theodolites` test the paper's expectation that devices
/// whose noise varies over the workspace profit more from weighting; `planned-poses` compares
/// planned with random poses (beyond the paper); `compliance` shows what a geometric
/// calibration misses on joints that deflect under gravity, and what identifying the
/// compliances gains.
pub const STUDIES: &[(&str, &str)] = &[
    ("paper-table1", include_str!("../../presets/paper-table1.toml")),
    ("paper-table2", include_str!("../../presets/paper-table2.toml")),
    ("device-cmm", include_str!("../../presets/device-cmm.toml")),
    ("device-laser-tracker", include_str!("../../presets/device-laser-tracker.toml")),
    ("device-theodolites", include_str!("../../presets/device-theodolites.toml")),
    ("planned-poses", include_str!("../../presets/planned-poses.toml")),
    ("compliance", include_str!("../../presets/compliance.toml")),
];
