//! Instruments compared: a Monte Carlo campaign that calibrates the same robots with different
//! measuring instruments at equal measurement time (issue #16's question, asked of
//! instruments rather than of estimators).
//!
//! # Procedure
//!
//! For each run `r = 1 .. R`:
//! 1. a "real" robot: the nominal parameters plus geometric errors on every joint parameter,
//!    normal with the study's sizes ([`ErrorSizes`], as [`Study`](super::Study) draws them);
//!    the base and the tool point exact. Every instrument measures the same real robot of run
//!    `r` (common random numbers), so that instruments compare run by run;
//! 2. for each instrument `i`, `N_i = floor(T / t_i)` observations (`T` the time budget, `t_i`
//!    the instrument's time per observation): at configurations uniform within the joint
//!    limits, the real robot at the read joint values plus the joint noise `n_q ~ N(0,
//!    Sigma_q)` (drawn anew at every pose), and the instrument's own noise `n_m ~ N(0,
//!    sigma_i^2)` on each measured number:
//!    - a laser tracker: the tool point's position `p + n_m` (3 numbers), calibrated by
//!      [`calibrate_kinds`] as a marker file (registration, base, marker and joints; the tracker's frame is the
//!      robot's base frame, which the calibration does not know);
//!    - a ball bar (or any distance to a fixed pivot `c`): `|p - c| + n_m`;
//!    - a length artefact: `|p_a - p_b| + n_m` between two configurations;
//!    - a plane probe: configurations where the tool point touches a plane `n_i . p = d_i +
//!      n_m`, the planes in turn (joint `j` of the largest `|d(n_i . p)/dq_j|` moved from a
//!      uniform configuration by Newton's method until it touches);
//!    - a height gauge: the tool point's height `e_z . p + n_m`;
//!    - a hand-eye camera (a wrist camera): the view `M = A^-1 W` of a target placed at `W` in
//!      the base frame by a camera mounted at `C` in the tip frame `T(q)`, `A = T(q) C`
//!      ([`camera`](crate::calibration::kinds::camera)), 6 numbers per view: its position
//!      plus `n_m` on each axis (mm) and its rotation turned by `exp([n_r]x)`, `n_r ~ N(0,
//!      sigma_r^2 I)` (the instrument's angle noise);
//!
//!    each of the last five calibrated by [`calibrate_kinds`], every joint parameter and the
//!    tool point asked for (the camera: the camera's mounting and the target's placement
//!    instead of the tool point, which it cannot see), weighted by `V_k` with the study's
//!    `Sigma_q` and `sigma_i` (WLS);
//! 3. each calibrated model scored over a common test set of configurations (uniform within
//!    the joint limits, drawn once per study): the position error after the best rigid
//!    alignment,
//!
//!    `E_p = (1/N_t) sum_t |T* p_hat(q_t) - p(q_t)|`, `T* = argmin_T sum_t |T p_hat(q_t) -
//!    p(q_t)|^2`
//!
//!    (Kabsch 1976), `p_hat` the calibrated model's tool point and `p` the real robot's,
//!    noise-free. A camera calibrates the tip frame and the camera's mounting together (what
//!    of the last link it cannot tell from the mounting, the mounting absorbs): its tool point
//!    rides with the calibrated camera, `p_hat(q) = T_hat(q) C_hat C^-1 t`, `t` the tool point
//!    in the tip frame and `C` the nominal mounting (the tool's offset from the camera taken as
//!    known, as it is in the simulation, where the real mounting is the nominal one). Distances and contacts cannot see where the robot stands (the base
//!    placement is held at its nominal value), and a user of such an instrument registers the
//!    robot to its work by other means; the alignment removes exactly what no instrument of
//!    the study is asked to deliver, and is applied to every instrument alike, the tracker
//!    too. Shape errors (joint geometry, scale) stay in `E_p`. [`Scores::unaligned`] keeps
//!    the error without alignment.
//!
//! The table gives, per instrument, the mean of `E_p` over the runs with its 95 % confidence
//! interval `mean +- t_{0.975, R-1} s / sqrt(R)`, and the paired difference against the first
//! instrument, `d_r = E_p,i(r) - E_p,1(r)`, with the same interval over the `d_r` (the common
//! real robots make it much narrower than the difference of two unpaired means).
//!
//! # Times per observation (the embedded `instruments` study)
//!
//! - laser tracker, 5 s per pose: the robot moves and settles (2-3 s), the tracker averages
//!   its reading (about 1 s) with one reflector, a little more with 2-3 markers;
//! - ball bar, 3 s per length: move, settle, read a digital probe;
//! - height gauge or plane touch, 4 s per contact: a slow approach to the surface and a
//!   retract;
//! - length artefact, 6 s per length: two poses, one per end of the artefact;
//! - wrist camera, 2 s per view: move, settle, one short exposure of the target (the board's
//!   pose computed from the image while the robot moves on).
//!
//! These are assumptions of a careful cell, not measured figures; a study file sets its own.
//!
//! The camera's views are drawn at configurations uniform within the joint limits, as every
//! other instrument's; with a [`Sight`] (the study file's `field_of_view_deg`, `range_mm`,
//! `max_incidence_deg`) only those where the real camera sees the target are kept (drawn again
//! until one is, at most [`MOST_DRAWS_PER_VIEW`] times), as a real wrist camera sees its board
//! from a narrower set of poses.
//!
//! # Random numbers
//!
//! Every stream is ChaCha8 seeded with the study's seed: the test set on
//! [`TEST_STREAM`](super), run `r`'s real robot on stream `r + 1`, instrument `i`'s
//! observations in run `r` on stream `((i + 1) << 32) | (r + 1)`. Runs and instruments are
//! spread over threads with rayon; the results are the same, bit for bit, on any number of
//! threads.

use super::{ErrorSizes, Redraw, SimulationError, StudyError, TEST_STREAM, draw_errors, normal, rng, stats};
use crate::calibration::kinds::camera::{isometry, placement};
use crate::calibration::kinds::{CameraSite, KindData, KindOptions, Observation, calibrate_kinds};
use crate::calibration::{CalibrationError, register};
use crate::error::FieldError;
use crate::kinematics::{Chain, ChainAt};
use crate::limits::{
    MAX_ANGLE_DEG, MAX_INSTRUMENT_WORK, MAX_LENGTH_MM, MAX_POINTS, MAX_RUNS_PER_CASE, MAX_STUDY_WORK,
    MAX_TEST_POINTS, check_magnitude,
};
use crate::model::{JointKind, ModelRef, RobotModel, Selection, Tool};
use nalgebra::{DMatrix, Isometry3, Point3, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::rngs::ChaCha8Rng;
use rayon::prelude::*;
use serde::Deserialize;

/// What an instrument measures, with the set-up it needs.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum InstrumentKind {
    /// A laser tracker: the tool point's position (3 numbers per observation).
    Tracker,
    /// A ball bar: the distance (mm) from the tool point to a fixed pivot (mm, base frame).
    BallBar {
        /// The pivot (mm, in the robot's base frame).
        pivot: Vector3<f64>,
    },
    /// A length artefact: the distance between the tool point at two configurations.
    Artefact,
    /// A touch probe on planes `n_i . p = d_i`, touched in turn.
    Plane {
        /// Each plane's unit normal (base frame) and offset `d_i` (mm).
        planes: Vec<(Vector3<f64>, f64)>,
    },
    /// A height gauge: the tool point's z (mm).
    HeightGauge,
    /// A hand-eye (wrist) camera: the pose of a target fixed in the base frame in the frame of
    /// a camera on the tool, 6 numbers per view (position mm, rotation); the instrument's
    /// `sigma` is the noise on each position number.
    Camera {
        /// The camera's mounting `C` in the tip frame (the frame the tool point is given in;
        /// position mm, rotation).
        mounting: Isometry3<f64>,
        /// The target's placement `W` in the robot's base frame (position mm, rotation).
        target: Isometry3<f64>,
        /// The noise on the view's rotation: the standard deviation of each component of the
        /// rotation vector of the error (rad).
        sigma_angle: f64,
        /// Where the camera sees the target from, if asked: views are drawn only there.
        sight: Option<Sight>,
    },
}

/// Where a camera sees its target from: the target's origin within `half_angle` of the
/// camera's optical axis (its z axis) and at a distance within `range`, and the camera within
/// `incidence` of the target's normal (its z axis), on its side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sight {
    /// Half the field of view's cone angle (rad).
    pub half_angle: f64,
    /// The nearest and farthest distance in focus (mm).
    pub range: [f64; 2],
    /// The largest angle between the target's normal and the line to the camera (rad).
    pub incidence: f64,
}

/// The most configurations drawn for one camera view before the target is taken to be out of
/// sight from every pose.
pub const MOST_DRAWS_PER_VIEW: usize = 100_000;

impl Sight {
    /// Whether the camera sees the target in the view `view` (the target's frame in the
    /// camera's): `angle(p, z) <= half_angle`, `range[0] <= |p| <= range[1]`, and
    /// `angle(c, z) <= incidence` for the camera's position `c` in the target's frame.
    pub fn sees(&self, view: &Isometry3<f64>) -> bool {
        let p = view.translation.vector;
        let c = view.inverse().translation.vector;
        let within = |v: &Vector3<f64>, limit: f64| v.z > 0.0 && v.z >= v.norm() * limit.cos();
        within(&p, self.half_angle)
            && (self.range[0]..=self.range[1]).contains(&p.norm())
            && within(&c, self.incidence)
    }
}

impl InstrumentKind {
    /// The kind's name in a study file: `tracker`, `ball-bar`, `artefact`, `plane`, `height`,
    /// `camera`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Tracker => "tracker",
            Self::BallBar { .. } => "ball-bar",
            Self::Artefact => "artefact",
            Self::Plane { .. } => "plane",
            Self::HeightGauge => "height",
            Self::Camera { .. } => "camera",
        }
    }
}

/// One instrument of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct Instrument {
    /// Its name in the table.
    pub name: String,
    /// What it measures.
    pub kind: InstrumentKind,
    /// Its measurement noise `sigma_i` (mm) on each measured number (a camera: on each
    /// position number of a view; its angle noise is in [`InstrumentKind::Camera`]).
    pub sigma: f64,
    /// The time one observation takes `t_i` (s).
    pub seconds: f64,
}

/// A validated instrument study: the robot, its errors and noise, the instruments and the
/// time budget, in mm and rad.
#[derive(Debug, Clone, PartialEq)]
pub struct InstrumentStudy {
    /// Short name, used in file names.
    pub name: String,
    /// What the study shows.
    pub description: String,
    /// The nominal robot; its tool point is the measured point.
    pub robot: RobotModel,
    /// Joint noise standard deviations (rad, mm for prismatic joints).
    pub joint_sigmas: Vec<f64>,
    /// The real robot's geometric errors (on every joint parameter; drawn every run).
    pub errors: ErrorSizes,
    /// The measurement time `T` every instrument gets (s).
    pub time_budget: f64,
    /// The instruments; the first is the reference of the paired differences.
    pub instruments: Vec<Instrument>,
    /// Runs (real robots).
    pub runs: usize,
    /// Configurations of the test set.
    pub test_points: usize,
    /// Master seed of every random stream.
    pub seed: u64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    name: String,
    #[serde(default)]
    description: String,
    robot: String,
    seed: u64,
    runs: usize,
    test_points: usize,
    time_budget_s: f64,
    noise: NoiseFile,
    errors: ErrorsFile,
    instruments: Vec<InstrumentFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoiseFile {
    joint_sigma: Vec<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ErrorsFile {
    offset_deg: f64,
    angle_deg: f64,
    length_mm: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InstrumentFile {
    name: String,
    kind: String,
    sigma_mm: f64,
    seconds_per_observation: f64,
    #[serde(default)]
    pivot_mm: Option<[f64; 3]>,
    #[serde(default)]
    planes: Option<Vec<PlaneFile>>,
    #[serde(default)]
    sigma_deg: Option<f64>,
    #[serde(default)]
    camera_xyz_mm: Option<[f64; 3]>,
    #[serde(default)]
    camera_rpy_deg: Option<[f64; 3]>,
    #[serde(default)]
    target_xyz_mm: Option<[f64; 3]>,
    #[serde(default)]
    target_rpy_deg: Option<[f64; 3]>,
    #[serde(default)]
    field_of_view_deg: Option<f64>,
    #[serde(default)]
    range_mm: Option<[f64; 2]>,
    #[serde(default)]
    max_incidence_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlaneFile {
    normal: [f64; 3],
    offset_mm: f64,
}

/// The instrument studies shipped with robocal: `(name, TOML text)`.
pub const INSTRUMENT_STUDIES: &[(&str, &str)] =
    &[("instruments", include_str!("../../presets/instruments.toml"))];

/// Whether `text` is an instrument study (it has `[[instruments]]`) rather than a
/// [`Study`](super::Study).
pub fn is_instrument_study(text: &str) -> bool {
    text.parse::<toml::Table>().is_ok_and(|t| t.contains_key("instruments"))
}

impl InstrumentStudy {
    /// Read a study from TOML text; `load_robot` turns the `robot` field (a preset name or a
    /// model file) into a model. See `docs/formats.md` for the fields.
    pub fn from_toml_str<E: Into<Box<dyn std::error::Error + Send + Sync>>>(
        text: &str,
        load_robot: impl FnOnce(&ModelRef) -> Result<RobotModel, E>,
    ) -> Result<Self, StudyError> {
        let file: File = toml::from_str(text).map_err(StudyError::Syntax)?;
        let reference = ModelRef { name: file.robot.clone(), base_link: None, tip_link: None, payload: None };
        let robot = load_robot(&reference).map_err(|e| StudyError::Robot(e.into()))?;
        let joint_sigmas = super::study::joint_sigmas(&robot, &file.noise.joint_sigma)?;
        let instruments = (file.instruments.iter().enumerate())
            .map(|(i, f)| f.instrument().map_err(|e| e.within(&format!("instruments[{i}]."))))
            .collect::<Result<_, _>>()?;
        let study = Self {
            name: file.name,
            description: file.description,
            robot,
            joint_sigmas,
            errors: ErrorSizes {
                offset: file.errors.offset_deg.to_radians(),
                angle: file.errors.angle_deg.to_radians(),
                length: file.errors.length_mm,
                redraw: Redraw::Run,
            },
            time_budget: file.time_budget_s,
            instruments,
            runs: file.runs,
            test_points: file.test_points,
            seed: file.seed,
        };
        study.check()?;
        Ok(study)
    }

    /// Check that the values make a study: a name fit for file names, one finite
    /// non-negative joint sigma per joint, error sizes finite >= 0 within [`crate::limits`], 2 or more runs, 1 or
    /// more test points, a finite positive time budget, and at least one instrument, each
    /// named (names distinct), with a noise finite >= 0, a time per observation > 0 and
    /// from 2 to [`MAX_POINTS`] observations in the budget (a camera: an angle noise finite >= 0,
    /// its mounting and target finite), and at most [`MAX_STUDY_WORK`]
    /// kinematic evaluations in all. Errors name the study file's
    /// field (`instruments[1].sigma_mm`).
    pub fn check(&self) -> Result<(), StudyError> {
        super::study::check_name(&self.name)?;
        self.check_noise_and_errors()?;
        self.check_sizes()?;
        for i in 0..self.instruments.len() {
            self.check_instrument(i)?;
        }
        self.check_work()
    }

    /// One joint sigma per joint, and the joint sigmas (deg; mm for a prismatic joint) and
    /// the error sizes finite >= 0 within [`MAX_ANGLE_DEG`] or [`MAX_LENGTH_MM`], field by
    /// field.
    fn check_noise_and_errors(&self) -> Result<(), StudyError> {
        super::study::check_joint_count(&self.robot, self.joint_sigmas.len())?;
        let joint = self.robot.joints.iter().zip(&self.joint_sigmas).map(|(j, &s)| match j.kind {
            JointKind::Revolute => ("noise.joint_sigma", s.to_degrees(), MAX_ANGLE_DEG, "deg"),
            JointKind::Prismatic => ("noise.joint_sigma", s, MAX_LENGTH_MM, "mm"),
        });
        let magnitudes = joint.chain([
            ("errors.offset_deg", self.errors.offset.to_degrees(), MAX_ANGLE_DEG, "deg"),
            ("errors.angle_deg", self.errors.angle.to_degrees(), MAX_ANGLE_DEG, "deg"),
            ("errors.length_mm", self.errors.length, MAX_LENGTH_MM, "mm"),
        ]);
        for (field, value, bound, unit) in magnitudes {
            super::study::check_non_negative(field, value)?;
            check_magnitude(value, bound, unit).map_err(|e| FieldError::new(field, e))?;
        }
        Ok(())
    }

    /// 2 to [`MAX_RUNS_PER_CASE`] runs, 1 to [`MAX_TEST_POINTS`] test points, a finite time
    /// budget > 0, and at least one instrument.
    fn check_sizes(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        for (field, count, low, high) in
            [("runs", self.runs, 2, MAX_RUNS_PER_CASE), ("test_points", self.test_points, 1, MAX_TEST_POINTS)]
        {
            if count < low || count > high {
                return invalid(field, format!("from {low} to {high}, found {count}"));
            }
        }
        if !(self.time_budget > 0.0 && self.time_budget.is_finite()) {
            return invalid("time_budget_s", format!("a time > 0 s, found {}", self.time_budget));
        }
        if self.instruments.is_empty() {
            return invalid("instruments", "at least one `[[instruments]]`".into());
        }
        Ok(())
    }

    /// Instrument `i`: a name of its own, a noise finite >= 0 within [`MAX_LENGTH_MM`], a
    /// camera's set-up ([`check_camera`]), its pivot or planes within [`MAX_LENGTH_MM`], a
    /// finite time per observation > 0 and from 2 to [`MAX_POINTS`] observations in the
    /// budget. Errors name `instruments[i].<field>`.
    fn check_instrument(&self, i: usize) -> Result<(), StudyError> {
        let instrument = &self.instruments[i];
        let field = |name: &str| format!("instruments[{i}].{name}");
        if instrument.name.is_empty() || self.instruments[..i].iter().any(|o| o.name == instrument.name) {
            let expected = format!("a name of its own, found {:?}", instrument.name);
            return Err(FieldError::new(field("name"), expected).into());
        }
        let sigma = instrument.sigma;
        if !(sigma >= 0.0 && sigma.is_finite()) {
            return Err(FieldError::new(field("sigma_mm"), format!("a noise >= 0 mm, found {sigma}")).into());
        }
        check_magnitude(sigma, MAX_LENGTH_MM, "mm").map_err(|e| FieldError::new(field("sigma_mm"), e))?;
        check_camera(&instrument.kind, &field)?;
        for (name, v) in setup_lengths(&instrument.kind, &field) {
            check_magnitude(v, MAX_LENGTH_MM, "mm").map_err(|e| FieldError::new(name, e))?;
        }
        let seconds = instrument.seconds;
        if !(seconds > 0.0 && seconds.is_finite()) {
            let expected = format!("a time > 0 s, found {seconds}");
            return Err(FieldError::new(field("seconds_per_observation"), expected).into());
        }
        let count = self.observations(i);
        if !(2..=MAX_POINTS).contains(&count) {
            let expected = format!(
                "from 2 to {MAX_POINTS} observations in time_budget_s ({} s), found {count}",
                self.time_budget
            );
            return Err(FieldError::new(field("seconds_per_observation"), expected).into());
        }
        Ok(())
    }

    /// The work of the whole study within bounds: at most [`MAX_STUDY_WORK`] kinematic
    /// evaluations, `runs x sum_i (N_i + test_points)`, and at most [`MAX_INSTRUMENT_WORK`]
    /// row-parameter products of the fits, `runs x sum_i N_i x 3 x parameters` (Jacobians of
    /// about 3 rows an observation by the robot's parameters, factorised).
    fn check_work(&self) -> Result<(), StudyError> {
        let invalid = |field: &str, expected: String| Err(FieldError::new(field, expected).into());
        let per_run = (0..self.instruments.len()).map(|i| (self.observations(i) + self.test_points) as u64);
        let work = per_run.sum::<u64>().saturating_mul(self.runs as u64);
        if work > MAX_STUDY_WORK {
            return invalid(
                "runs",
                format!(
                    "a study of at most {MAX_STUDY_WORK:e} kinematic evaluations (runs x instruments x \
                     (observations + test_points)), found {work:e}"
                ),
            );
        }
        // Each run fits every instrument's observations: Jacobians of about 3 rows a
        // observation by the robot's parameters, factorised.
        let rows_by_params = 3 * self.robot.params().len() as u64;
        let observations: u64 = (0..self.instruments.len()).map(|i| self.observations(i) as u64).sum();
        let solve_work = observations.saturating_mul(rows_by_params).saturating_mul(self.runs as u64);
        if solve_work > MAX_INSTRUMENT_WORK {
            return invalid(
                "time_budget_s",
                format!(
                    "a study of at most {:.0e} row-parameter products (runs x observations x 3 rows x {} \
                     parameters), found about {solve_work:.1e}: hours of work; ask for a shorter time budget or \
                     fewer runs",
                    MAX_INSTRUMENT_WORK as f64,
                    self.robot.params().len()
                ),
            );
        }
        Ok(())
    }

    /// `N_i = floor(T / t_i)`: instrument `i`'s observations in the time budget.
    pub fn observations(&self, i: usize) -> usize {
        let n = (self.time_budget / self.instruments[i].seconds).floor();
        if n >= MAX_POINTS as f64 { MAX_POINTS + 1 } else { n as usize }
    }

    /// The measured point: the robot's tool point in its marker frame (mm).
    fn tool(&self) -> Vector3<f64> {
        match self.robot.tool {
            Tool::Point(p) => p,
            Tool::Frame(_) => Vector3::zeros(),
        }
    }
}

impl InstrumentFile {
    /// The instrument this entry describes; errors name the field within the entry.
    fn instrument(&self) -> Result<Instrument, FieldError> {
        let kind = match self.kind.as_str() {
            "tracker" => InstrumentKind::Tracker,
            "ball-bar" => self.ball_bar()?,
            "artefact" => InstrumentKind::Artefact,
            "plane" => self.plane()?,
            "height" => InstrumentKind::HeightGauge,
            "camera" => self.camera()?,
            other => {
                let expected =
                    format!("tracker, ball-bar, artefact, plane, height or camera, found {other:?}");
                return Err(FieldError::new("kind", expected));
            }
        };
        self.check_unused(&kind)?;
        Ok(Instrument {
            name: self.name.clone(),
            kind,
            sigma: self.sigma_mm,
            seconds: self.seconds_per_observation,
        })
    }

    /// A ball bar about `pivot_mm`, given and finite.
    fn ball_bar(&self) -> Result<InstrumentKind, FieldError> {
        let pivot = self
            .pivot_mm
            .ok_or_else(|| FieldError::new("pivot_mm", "the pivot [x, y, z] (mm, base frame)"))?;
        if pivot.iter().any(|v| !v.is_finite()) {
            return Err(FieldError::new("pivot_mm", "finite numbers"));
        }
        Ok(InstrumentKind::BallBar { pivot: pivot.into() })
    }

    /// A plane probe on the `planes`, at least one, each with a finite non-zero normal
    /// (normalised, `n / |n|`) and a finite offset.
    fn plane(&self) -> Result<InstrumentKind, FieldError> {
        let files = self.planes.as_deref().unwrap_or_default();
        if files.is_empty() {
            let expected = "the planes touched: [{ normal = [x, y, z], offset_mm = d }, ...]";
            return Err(FieldError::new("planes", expected));
        }
        let mut planes = Vec::with_capacity(files.len());
        for (k, plane) in files.iter().enumerate() {
            let normal = Vector3::from(plane.normal);
            if !(normal.iter().all(|v| v.is_finite()) && normal.norm() > 1e-9) {
                return Err(FieldError::new(format!("planes[{k}].normal"), "a finite non-zero vector"));
            }
            if !plane.offset_mm.is_finite() {
                return Err(FieldError::new(format!("planes[{k}].offset_mm"), "a finite number (mm)"));
            }
            planes.push((normal.normalize(), plane.offset_mm));
        }
        Ok(InstrumentKind::Plane { planes })
    }

    /// A wrist camera: its mounting and target frames ([`frame`]), its angle noise (deg in
    /// the file, rad here) and its [`Sight`], if asked.
    fn camera(&self) -> Result<InstrumentKind, FieldError> {
        let mounting = frame(
            ("camera_xyz_mm", self.camera_xyz_mm),
            ("camera_rpy_deg", self.camera_rpy_deg),
            "the camera's mounting in the tip frame",
        )?;
        let target = frame(
            ("target_xyz_mm", self.target_xyz_mm),
            ("target_rpy_deg", self.target_rpy_deg),
            "the target's placement in the base frame",
        )?;
        let sigma_deg = self
            .sigma_deg
            .ok_or_else(|| FieldError::new("sigma_deg", "the noise on each angle of a view (deg)"))?;
        let sight = self.sight()?;
        Ok(InstrumentKind::Camera { mounting, target, sigma_angle: sigma_deg.to_radians(), sight })
    }

    /// A camera's [`Sight`] from `field_of_view_deg` (a full cone angle in (0, 180) deg,
    /// halved), `range_mm` (`0 <= near < far`) and `max_incidence_deg` (in (0, 90] deg): all
    /// three, or none (no sight: every view is kept).
    fn sight(&self) -> Result<Option<Sight>, FieldError> {
        match (self.field_of_view_deg, self.range_mm, self.max_incidence_deg) {
            (None, None, None) => Ok(None),
            (Some(fov), Some(range), Some(incidence)) => {
                if !(fov > 0.0 && fov < 180.0) {
                    let expected = format!("a full cone angle above 0 and below 180 deg, found {fov}");
                    return Err(FieldError::new("field_of_view_deg", expected));
                }
                if !(range[0] >= 0.0 && range[0] < range[1] && range[1].is_finite()) {
                    return Err(FieldError::new("range_mm", "[near, far] with 0 <= near < far (mm)"));
                }
                if !(incidence > 0.0 && incidence <= 90.0) {
                    let expected = format!("an angle above 0 and at most 90 deg, found {incidence}");
                    return Err(FieldError::new("max_incidence_deg", expected));
                }
                Ok(Some(Sight {
                    half_angle: (fov / 2.0).to_radians(),
                    range,
                    incidence: incidence.to_radians(),
                }))
            }
            _ => Err(FieldError::new(
                "field_of_view_deg",
                "field_of_view_deg, range_mm and max_incidence_deg together, or none of them",
            )),
        }
    }

    /// The fields of one kind given to another: `pivot_mm` only for a ball bar, `planes`
    /// only for a plane probe, the camera's fields only for a camera.
    fn check_unused(&self, kind: &InstrumentKind) -> Result<(), FieldError> {
        let unused = |field: &str, present: bool, kind: &str| match present {
            true => Err(FieldError::new(field, format!("only for kind = \"{kind}\", not {:?}", self.kind))),
            false => Ok(()),
        };
        unused(
            "pivot_mm",
            self.pivot_mm.is_some() && !matches!(kind, InstrumentKind::BallBar { .. }),
            "ball-bar",
        )?;
        unused("planes", self.planes.is_some() && !matches!(kind, InstrumentKind::Plane { .. }), "plane")?;
        let camera = matches!(kind, InstrumentKind::Camera { .. });
        for (field, present) in [
            ("sigma_deg", self.sigma_deg.is_some()),
            ("camera_xyz_mm", self.camera_xyz_mm.is_some()),
            ("camera_rpy_deg", self.camera_rpy_deg.is_some()),
            ("target_xyz_mm", self.target_xyz_mm.is_some()),
            ("target_rpy_deg", self.target_rpy_deg.is_some()),
            ("field_of_view_deg", self.field_of_view_deg.is_some()),
            ("range_mm", self.range_mm.is_some()),
            ("max_incidence_deg", self.max_incidence_deg.is_some()),
        ] {
            unused(field, present && !camera, "camera")?;
        }
        Ok(())
    }
}

/// A frame of a camera's set-up, `what`, from its position (`xyz_field`, mm) and rotation
/// (`rpy_field`, deg, `R = Rz(yaw) Ry(pitch) Rx(roll)`), both given and finite.
fn frame(
    (xyz_field, xyz): (&str, Option<[f64; 3]>),
    (rpy_field, rpy): (&str, Option<[f64; 3]>),
    what: &str,
) -> Result<Isometry3<f64>, FieldError> {
    let xyz = xyz.ok_or_else(|| FieldError::new(xyz_field, format!("{what}: [x, y, z] (mm)")))?;
    let rpy = rpy.ok_or_else(|| {
        let expected = format!("{what}: [roll, pitch, yaw] (deg, R = Rz(yaw) Ry(pitch) Rx(roll))");
        FieldError::new(rpy_field, expected)
    })?;
    if xyz.iter().any(|v| !v.is_finite()) {
        return Err(FieldError::new(xyz_field, "finite numbers (mm)"));
    }
    if rpy.iter().any(|v| !v.is_finite()) {
        return Err(FieldError::new(rpy_field, "finite angles (deg)"));
    }
    let [roll, pitch, yaw] = rpy.map(f64::to_radians);
    Ok(Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    ))
}

/// A camera's set-up (other kinds pass): an angle noise finite >= 0 within
/// [`MAX_ANGLE_DEG`], and its mounting and target with positions within [`MAX_LENGTH_MM`]
/// and finite rotations. `field` names a field of the instrument's entry.
fn check_camera(kind: &InstrumentKind, field: &dyn Fn(&str) -> String) -> Result<(), StudyError> {
    let InstrumentKind::Camera { mounting, target, sigma_angle, .. } = kind else { return Ok(()) };
    let degrees = sigma_angle.to_degrees();
    if !(degrees >= 0.0 && degrees.is_finite()) {
        let expected = format!("a noise >= 0 deg, found {degrees}");
        return Err(FieldError::new(field("sigma_deg"), expected).into());
    }
    check_magnitude(degrees, MAX_ANGLE_DEG, "deg").map_err(|e| FieldError::new(field("sigma_deg"), e))?;
    for (name, frame) in [("camera_xyz_mm", mounting), ("target_xyz_mm", target)] {
        for &v in frame.translation.vector.iter() {
            check_magnitude(v, MAX_LENGTH_MM, "mm").map_err(|e| FieldError::new(field(name), e))?;
        }
        if !frame.rotation.coords.iter().all(|v| v.is_finite()) {
            let name = name.replace("xyz_mm", "rpy_deg");
            return Err(FieldError::new(field(&name), "finite angles (deg)").into());
        }
    }
    Ok(())
}

/// The lengths of an instrument's set-up with their fields (a ball bar's pivot, a plane
/// probe's plane offsets; none for other kinds): a pivot or plane a kilometre out is no ball
/// bar or table.
fn setup_lengths(kind: &InstrumentKind, field: &dyn Fn(&str) -> String) -> Vec<(String, f64)> {
    match kind {
        InstrumentKind::BallBar { pivot } => pivot.iter().map(|&v| (field("pivot_mm"), v)).collect(),
        InstrumentKind::Plane { planes } => (planes.iter().enumerate())
            .map(|(k, plane)| (field(&format!("planes[{k}].offset_mm")), plane.1))
            .collect(),
        _ => Vec::new(),
    }
}

/// The errors of one calibrated model over the test set (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// Mean position error after the best rigid alignment, `E_p` of the [module](self).
    pub aligned: f64,
    /// Mean position error without alignment.
    pub unaligned: f64,
}

/// Everything an instrument study produced.
#[derive(Debug, Clone, PartialEq)]
pub struct InstrumentResults {
    /// `scores[r][i]`: run `r`, instrument `i`.
    pub scores: Vec<Vec<Scores>>,
    /// The nominal (uncalibrated) model's scores, run by run.
    pub nominal: Vec<Scores>,
}

impl InstrumentResults {
    /// Instrument `i`'s `E_p` (aligned), run by run.
    pub fn errors(&self, i: usize) -> Vec<f64> {
        self.scores.iter().map(|r| r[i].aligned).collect()
    }

    /// Mean and 95 % half width `t_{0.975, R-1} s / sqrt(R)` of instrument `i`'s `E_p`.
    pub fn mean_error(&self, i: usize) -> (f64, f64) {
        interval(&self.errors(i))
    }

    /// Mean and 95 % half width of the paired differences `E_p,i(r) - E_p,1(r)`.
    pub fn paired_difference(&self, i: usize) -> (f64, f64) {
        let d: Vec<f64> = self.scores.iter().map(|r| r[i].aligned - r[0].aligned).collect();
        interval(&d)
    }
}

/// The mean of `values` and its 95 % half width `t_{0.975, n-1} s / sqrt(n)`.
pub fn interval(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    let half = stats::t_quantile_975(n.saturating_sub(1)) * (stats::variance(values) / n as f64).sqrt();
    (stats::mean(values), half)
}

/// The standard deviation an exact instrument (`sigma_mm = 0`) declares (mm): weights need
/// one, and exact data fit exactly whatever it is.
pub const EXACT_SIGMA_MM: f64 = 0.001;

/// The angle standard deviation an exact camera (`sigma_deg = 0`) declares (deg).
pub const EXACT_SIGMA_DEG: f64 = 0.0001;

/// What every run shares: the chain of the measured point, the test set.
struct Campaign<'a> {
    study: &'a InstrumentStudy,
    chain: Chain,
    joints: Selection,
    test: Vec<Vec<f64>>,
}

/// Run `study` ([module](self)), calling `progress` once per calibration (from any thread).
/// The study is checked first ([`InstrumentStudy::check`]).
pub fn run_instruments(
    study: &InstrumentStudy,
    progress: &(dyn Fn() + Sync),
) -> Result<InstrumentResults, SimulationError> {
    let whole = run_instruments_shard(study, super::Shard::WHOLE, progress)?;
    Ok(InstrumentResults::merge(study, [whole]).expect("one shard is the whole study"))
}

/// A shard's part of an instrument study: the scores of its calibrations, which are the
/// (run, instrument) pairs `first`, `first + 1`, ... in their order (run by run, instrument by
/// instrument), and the nominal model's scores (every shard computes them).
#[derive(Debug, Clone, PartialEq)]
pub struct InstrumentPart {
    /// The first calibration's place among all of them.
    pub first: usize,
    /// The scores of the shard's calibrations.
    pub scores: Vec<Scores>,
    /// The nominal model's scores, run by run.
    pub nominal: Vec<Scores>,
}

impl InstrumentResults {
    /// The results of a study's shards together, exactly as the study run whole gives them;
    /// `None` unless the parts hold each calibration of `study` once.
    pub fn merge(study: &InstrumentStudy, parts: impl IntoIterator<Item = InstrumentPart>) -> Option<Self> {
        let mut parts: Vec<InstrumentPart> = parts.into_iter().collect();
        parts.sort_by_key(|p| p.first);
        let mut scores = Vec::new();
        for part in &parts {
            if part.first != scores.len() || part.nominal.len() != study.runs {
                return None;
            }
            scores.extend_from_slice(&part.scores);
        }
        let instruments = study.instruments.len();
        if scores.len() != study.runs * instruments {
            return None;
        }
        let nominal = parts.first()?.nominal.clone();
        Some(Self { scores: scores.chunks(instruments).map(<[Scores]>::to_vec).collect(), nominal })
    }
}

/// Shard `shard` ([`super::Shard`]) of `study`: its share of the (run, instrument)
/// calibrations in their order, calling `progress` once per calibration.
pub fn run_instruments_shard(
    study: &InstrumentStudy,
    shard: super::Shard,
    progress: &(dyn Fn() + Sync),
) -> Result<InstrumentPart, SimulationError> {
    study.check()?;
    let chain = Chain::markers(&study.robot, &[study.tool()]).remove(0);
    let joints = Selection::joints(chain.params());
    let test = study.robot.uniform_configurations(study.test_points, &mut rng(study.seed, TEST_STREAM));
    let campaign = Campaign { study, chain, joints, test };
    let truths: Vec<Vec<f64>> = (0..study.runs)
        .map(|r| {
            let mut rng = rng(study.seed, r as u64 + 1);
            draw_errors(campaign.chain.params(), campaign.joints.indices(), &study.errors, &mut rng)
        })
        .collect();
    let instruments = study.instruments.len();
    let range = shard.range(study.runs * instruments);
    let first = range.start;
    let pairs: Vec<(usize, usize)> = range.map(|g| (g / instruments, g % instruments)).collect();
    let scores: Vec<Scores> = pairs
        .par_iter()
        .map(|&(r, i)| {
            let score = campaign.calibrate(&truths[r], r, i);
            progress();
            score
        })
        .collect::<Result<_, _>>()?;
    let nominal = campaign.chain.with_errors(&vec![0.0; campaign.chain.params().len()]);
    let nominal: Vec<Vector3<f64>> = campaign.test.iter().map(|q| nominal.position(q)).collect();
    let nominal = truths.iter().map(|t| campaign.score(&nominal, &campaign.chain.with_errors(t))).collect();
    Ok(InstrumentPart { first, scores, nominal })
}

impl Campaign<'_> {
    /// Steps 2 and 3 of the [module](self) for run `run` (real robot errors `truth`) and
    /// instrument `i`.
    fn calibrate(&self, truth: &[f64], run: usize, i: usize) -> Result<Scores, SimulationError> {
        let study = self.study;
        let instrument = &study.instruments[i];
        let real = self.chain.with_errors(truth);
        let mut rng = rng(study.seed, ((i as u64 + 1) << 32) | (run as u64 + 1));
        let count = study.observations(i);
        let declared = if instrument.sigma > 0.0 { instrument.sigma } else { EXACT_SIGMA_MM };
        let noise_q = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            study.joint_sigmas.len(),
            study.joint_sigmas.iter().map(|s| s * s),
        ));
        let data = match &instrument.kind {
            InstrumentKind::Tracker => self.tracker(&real, count, instrument.sigma, declared, &mut rng),
            _ => self.kinds(&real, i, count, declared, &mut rng)?,
        };
        // The tracker's marker is the tool point; the other kinds see the tool point itself.
        let options = KindOptions {
            joint_noise: Some(noise_q),
            markers: vec![study.tool()],
            tool: study.tool(),
            ..KindOptions::default()
        };
        let c = calibrate_kinds(&study.robot, &data, &options).map_err(calibration_error)?;
        let tool = match &instrument.kind {
            // The calibrated camera's mounting in the calibrated tip frame; the tool point at
            // its nominal offset from the camera.
            InstrumentKind::Camera { mounting, .. } => {
                let at = c.setup.names().iter().position(|n| n == "camera.x").expect("a camera's set-up");
                isometry(&c.setup_values.1[at..at + 6]) * mounting.inverse()
            }
            _ => Isometry3::identity(),
        };
        let predicted = self.tool_points(&c.calibrated, &tool);
        Ok(self.score(&predicted, &real))
    }

    /// The tool points of the calibrated model `calibrated` over the test set, its tool frame
    /// moved by `correction` (a camera's: its tool point rides with the calibrated camera).
    fn tool_points(&self, calibrated: &RobotModel, correction: &Isometry3<f64>) -> Vec<Vector3<f64>> {
        let model = Chain::new(calibrated);
        let at = model.with_errors(&vec![0.0; model.params().len()]);
        let tool = match calibrated.tool {
            Tool::Point(p) => p,
            Tool::Frame(_) => self.study.tool(),
        };
        let tool = Point3::from(tool);
        self.test
            .iter()
            .map(|q| match calibrated.tool {
                Tool::Point(_) => at.position(q),
                Tool::Frame(_) => (at.pose(q) * correction * tool).coords,
            })
            .collect()
    }

    /// The joint values `q` read with the joint noise: `q + n_q`.
    fn noisy(&self, q: &[f64], rng: &mut ChaCha8Rng) -> Vec<f64> {
        q.iter().zip(&self.study.joint_sigmas).map(|(q, s)| q + s * normal(rng)).collect()
    }

    /// The real robot's tool point at `q` read with the joint noise: at `q + n_q`.
    fn at_noisy(&self, real: &ChainAt, q: &[f64], rng: &mut ChaCha8Rng) -> Vector3<f64> {
        real.position(&self.noisy(q, rng))
    }

    /// A tracker's `count` positions, noise `sigma` on each axis, declared `declared`.
    fn tracker(
        &self,
        real: &ChainAt,
        count: usize,
        sigma: f64,
        declared: f64,
        rng: &mut ChaCha8Rng,
    ) -> KindData {
        let joints = self.study.robot.uniform_configurations(count, rng);
        let mut data = KindData::default();
        for (pose, q) in joints.iter().enumerate() {
            let p = self.at_noisy(real, q, rng);
            let measured = p + Vector3::new(normal(rng), normal(rng), normal(rng)) * sigma;
            for axis in 0..3 {
                let sigma = declared;
                data.observations.push(Observation::Marker {
                    marker: 0,
                    axis,
                    pose,
                    measured: measured[axis],
                    sigma,
                });
                data.lines.push(pose + 1);
            }
        }
        data.joints = joints;
        data
    }

    /// `count` observations of instrument `i` (not a tracker) with its noise, declared
    /// `declared`.
    fn kinds(
        &self,
        real: &ChainAt,
        i: usize,
        count: usize,
        declared: f64,
        rng: &mut ChaCha8Rng,
    ) -> Result<KindData, SimulationError> {
        let (kind, sigma) = (&self.study.instruments[i].kind, self.study.instruments[i].sigma);
        let mut data = KindData::default();
        for k in 0..count {
            let pose = data.joints.len();
            let observation = match kind {
                InstrumentKind::Camera { mounting, target, sigma_angle, sight } => {
                    let seen = |q: &[f64]| self.view(real, mounting, target, q);
                    let q = self.configuration_in_sight(i, sight.as_ref(), &seen, rng)?;
                    let view = noisy_view(&seen(&self.noisy(&q, rng)), sigma, *sigma_angle, rng);
                    push_views(&mut data, q, view, k + 1, declared, *sigma_angle);
                    continue;
                }
                &InstrumentKind::BallBar { pivot } => {
                    let (q, measured) = self.ball_bar_length(real, pivot, sigma, rng);
                    data.joints.push(q);
                    Observation::ToPoint { pose, point: 0, measured, sigma: declared }
                }
                InstrumentKind::Artefact => {
                    let (ends, measured) = self.artefact_length(real, sigma, rng);
                    data.joints.extend(ends);
                    Observation::Distance { a: pose, b: pose + 1, measured, sigma: declared }
                }
                InstrumentKind::HeightGauge => {
                    let (q, measured) = self.height(real, sigma, rng);
                    data.joints.push(q);
                    Observation::Coordinate { pose, axis: 2, measured, sigma: declared }
                }
                InstrumentKind::Plane { planes } => {
                    let plane = k % planes.len();
                    data.joints.push(self.contact(real, i, plane, planes[plane], sigma, rng)?);
                    Observation::Contact { pose, plane, sigma: declared }
                }
                InstrumentKind::Tracker => unreachable!("a tracker is calibrated from marker positions"),
            };
            data.observations.push(observation);
            data.lines.push(k + 1);
        }
        Ok(data)
    }

    /// The view `(T(q) T_t^-1 C)^-1 W` of the target placed at `target` (`W`) from the camera
    /// mounted at `mounting` (`C`) on the real robot at `q`: the tool point's frame `T(q)`
    /// moved back to the tip frame by the tool point `t` (`T_t` the translation by `t`).
    fn view(
        &self,
        real: &ChainAt,
        mounting: &Isometry3<f64>,
        target: &Isometry3<f64>,
        q: &[f64],
    ) -> Isometry3<f64> {
        let tip = real.pose(q) * Translation3::from(-self.study.tool());
        (tip * mounting).inverse() * target
    }

    /// A configuration uniform within the joint limits from which camera `i` sees its target
    /// (`seen` the view at a configuration): drawn again until [`Sight::sees`] the view, at
    /// most [`MOST_DRAWS_PER_VIEW`] times; the first drawn without a `sight`.
    fn configuration_in_sight(
        &self,
        i: usize,
        sight: Option<&Sight>,
        seen: &dyn Fn(&[f64]) -> Isometry3<f64>,
        rng: &mut ChaCha8Rng,
    ) -> Result<Vec<f64>, SimulationError> {
        let robot = &self.study.robot;
        let mut q = robot.uniform_configurations(1, rng).remove(0);
        if let Some(sight) = sight {
            let mut draws = 1;
            while !sight.sees(&seen(&q)) {
                if draws == MOST_DRAWS_PER_VIEW {
                    let field = format!("instruments[{i}].field_of_view_deg");
                    let expected = format!(
                        "a target the camera sees from some poses: none of {MOST_DRAWS_PER_VIEW} drawn did"
                    );
                    return Err(StudyError::from(FieldError::new(field, expected)).into());
                }
                q = robot.uniform_configurations(1, rng).remove(0);
                draws += 1;
            }
        }
        Ok(q)
    }

    /// A ball bar's length at a uniform configuration `q`: `|p(q + n_q) - c| + n_m`, `c` the
    /// pivot and `n_m ~ N(0, sigma^2)`; with `q`.
    fn ball_bar_length(
        &self,
        real: &ChainAt,
        pivot: Vector3<f64>,
        sigma: f64,
        rng: &mut ChaCha8Rng,
    ) -> (Vec<f64>, f64) {
        let q = self.study.robot.uniform_configurations(1, rng).remove(0);
        let measured = (self.at_noisy(real, &q, rng) - pivot).norm() + sigma * normal(rng);
        (q, measured)
    }

    /// A length artefact's length between two uniform configurations `a` and `b`:
    /// `|p(a + n_q) - p(b + n_q')| + n_m`, `n_m ~ N(0, sigma^2)`; with `[a, b]`.
    fn artefact_length(&self, real: &ChainAt, sigma: f64, rng: &mut ChaCha8Rng) -> (Vec<Vec<f64>>, f64) {
        let ends = self.study.robot.uniform_configurations(2, rng);
        let (a, b) = (self.at_noisy(real, &ends[0], rng), self.at_noisy(real, &ends[1], rng));
        let measured = (a - b).norm() + sigma * normal(rng);
        (ends, measured)
    }

    /// A height gauge's reading at a uniform configuration `q`: `e_z . p(q + n_q) + n_m`,
    /// `n_m ~ N(0, sigma^2)`; with `q`.
    fn height(&self, real: &ChainAt, sigma: f64, rng: &mut ChaCha8Rng) -> (Vec<f64>, f64) {
        let q = self.study.robot.uniform_configurations(1, rng).remove(0);
        let measured = self.at_noisy(real, &q, rng).z + sigma * normal(rng);
        (q, measured)
    }

    /// The joints read (with their noise) at a configuration where the real tool point
    /// touches plane `plane` of plane probe `i`, `n . p = d + n_m` (`n`, `d` that plane's) ([`Self::touch`]); an
    /// error names the plane if the tool point cannot reach it.
    fn contact(
        &self,
        real: &ChainAt,
        i: usize,
        plane: usize,
        (n, offset): (Vector3<f64>, f64),
        sigma: f64,
        rng: &mut ChaCha8Rng,
    ) -> Result<Vec<f64>, SimulationError> {
        let target = offset + sigma * normal(rng);
        let touching = self.touch(real, n, target, rng).ok_or_else(|| {
            let field = format!("instruments[{i}].planes[{plane}]");
            StudyError::from(FieldError::new(field, "a plane the robot's tool point reaches"))
        })?;
        // The joints read with their noise at the touching configuration.
        Ok(self.noisy(&touching, rng))
    }

    /// A configuration where the real robot's tool point lies on `n . p = d`: from uniform
    /// configurations, Newton's method on the joint of the largest `|d(n . p)/dq_j|` (central
    /// differences); at most 1000 tries.
    fn touch(&self, real: &ChainAt, n: Vector3<f64>, d: f64, rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        let robot = &self.study.robot;
        let f = |q: &[f64]| n.dot(&real.position(q)) - d;
        let slope = |q: &mut Vec<f64>, j: usize| {
            let h = 1e-6;
            q[j] += h;
            let plus = f(q);
            q[j] -= 2.0 * h;
            let minus = f(q);
            q[j] += h;
            (plus - minus) / (2.0 * h)
        };
        for _ in 0..1000 {
            let mut q = robot.uniform_configurations(1, rng).remove(0);
            let j = (0..q.len())
                .map(|j| (j, slope(&mut q, j).abs()))
                .fold((0, 0.0), |best, (j, s)| if s > best.1 { (j, s) } else { best })
                .0;
            for _ in 0..30 {
                let value = f(&q);
                if value.abs() < 1e-10 {
                    break;
                }
                let s = slope(&mut q, j);
                if s.abs() < 1e-9 {
                    break;
                }
                q[j] -= (value / s).clamp(-0.5, 0.5);
            }
            let limits = robot.joints[j].limits;
            if f(&q).abs() < 1e-9 && q[j] >= limits[0] && q[j] <= limits[1] {
                return Some(q);
            }
        }
        None
    }

    /// The tool points `predicted` of a model over the test set against the real robot's:
    /// [`Scores`].
    fn score(&self, predicted: &[Vector3<f64>], real: &ChainAt) -> Scores {
        let truth: Vec<Vector3<f64>> = self.test.iter().map(|q| real.position(q)).collect();
        let t = register(predicted, &truth);
        let n = self.test.len() as f64;
        let mean = |f: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
            predicted.iter().zip(&truth).map(|(p, r)| (f(p) - r).norm()).sum::<f64>() / n
        };
        Scores { aligned: mean(&|p| t.transform_point(&(*p).into()).coords), unaligned: mean(&|p| *p) }
    }
}

/// A camera's `view` with its noise: `n_m ~ N(0, sigma^2)` on each position number, and the
/// rotation turned by `exp([n_r]x)`, `n_r ~ N(0, sigma_angle^2 I)`; as
/// [`placement`] numbers.
fn noisy_view(view: &Isometry3<f64>, sigma: f64, sigma_angle: f64, rng: &mut ChaCha8Rng) -> Vector6<f64> {
    let mut z = || Vector3::new(normal(rng), normal(rng), normal(rng));
    let position = view.translation.vector + z() * sigma;
    let rotation = UnitQuaternion::from_scaled_axis(z() * sigma_angle) * view.rotation;
    placement(&Isometry3::from_parts(position.into(), rotation))
}

/// A camera's `view` at the configuration `q` as the 6 observations of `data` (one per
/// axis, line `line`): the position's declared `declared`, the rotation's `sigma_angle` (or
/// [`EXACT_SIGMA_DEG`] for an exact camera).
fn push_views(
    data: &mut KindData,
    q: Vec<f64>,
    view: Vector6<f64>,
    line: usize,
    declared: f64,
    sigma_angle: f64,
) {
    let pose = data.joints.len();
    let declared_angle = if sigma_angle > 0.0 { sigma_angle } else { EXACT_SIGMA_DEG.to_radians() };
    data.joints.push(q);
    for axis in 0..6 {
        let sigma = if axis < 3 { declared } else { declared_angle };
        data.observations.push(Observation::Camera { axis, pose, view, site: CameraSite::Hand, sigma });
        data.lines.push(line);
    }
}

fn calibration_error(e: CalibrationError) -> SimulationError {
    match e {
        CalibrationError::Estimation(e) => SimulationError::Estimation(e),
        other => SimulationError::Calibration(other),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane probe's configurations touch their plane on the real robot, within the limits,
    /// and an unreachable plane is none.
    #[test]
    fn touching_configurations_lie_on_the_plane() {
        let robot = RobotModel::preset("puma560").unwrap();
        let study_text = INSTRUMENT_STUDIES[0].1;
        let mut study =
            InstrumentStudy::from_toml_str(study_text, |_| Ok::<_, String>(robot.clone())).unwrap();
        study.test_points = 1;
        let chain = Chain::markers(&robot, &[study.tool()]).remove(0);
        let joints = Selection::joints(chain.params());
        let campaign = Campaign { study: &study, chain, joints, test: Vec::new() };
        let mut rng = rng(7, 1);
        let truth = draw_errors(campaign.chain.params(), campaign.joints.indices(), &study.errors, &mut rng);
        let real = campaign.chain.with_errors(&truth);
        let n = Vector3::new(1.0, 1.0, 0.0).normalize();
        for _ in 0..20 {
            let q = campaign.touch(&real, n, 300.0, &mut rng).expect("a reachable plane");
            assert!((n.dot(&real.position(&q)) - 300.0).abs() < 1e-9);
            assert!(q.iter().zip(&robot.joints).all(|(q, j)| *q >= j.limits[0] && *q <= j.limits[1]));
        }
        assert!(campaign.touch(&real, n, 5000.0, &mut rng).is_none(), "5 m away");
    }
}
