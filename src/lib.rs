//! # robocal
//!
//! Kinematic calibration of serial robot arms by ordinary and weighted (Gauss-Markov) least
//! squares, after G. Zak, B. Benhabib, R. G. Fenton and I. Saban, "Application of the
//! Weighted Least Squares Parameter Estimation Method to the Robot Calibration", ASME J.
//! Mechanical Design.
//!
//! The errors of a robot's kinematic parameters `x` are found from measured end-effector
//! positions or poses through the linearised model `y = H x + e` (the paper's Eq. 1).
//!
//! The modules, from the bottom up; each uses only the modules above it in this list, never
//! one below (a test in `tests/integration/layering.rs` keeps it so):
//! - [`error`]: the error vocabulary the input formats share. [`limits`]: the bounds of every
//!   size and magnitude an input controls.
//! - [`model`]: robot models (DH conventions with Hayati's beta, URDF, base, tool, limits),
//!   their TOML format, and the named error parameters.
//! - [`kinematics`]: forward kinematics, the manipulator Jacobian `J` and the identification
//!   Jacobian `H`, analytic and allocation-free; the gravity load on each joint, and joints
//!   that deflect under it (compliance). [`table`]: the CSV tables of joint values and
//!   measurements, beside it.
//! - [`estimation`]: the noise model (`V_k = J_k Sigma_q J_k^T + Sigma_m,k`), OLS and weighted
//!   (Gauss-Markov) least squares by whitening, rank-deficient solves, identifiability,
//!   covariance, and Gauss-Newton refinement.
//! - [`calibration`]: calibrating a real robot from measured data of every kind (marker
//!   positions, a probe's poses, distances, plane contacts, coordinates, camera views, views
//!   on a tree): registration, the set-up, identifiable joint parameters, validation. [`design`], beside it:
//!   choosing the measurement poses (beyond the paper): observability indices O1-O5 of a pose
//!   set, and poses planned by an exchange algorithm to maximise one of them.
//! - [`simulation`]: the Monte Carlo simulation of a calibration campaign (the paper's steps
//!   1-8), studies as data, reproducible on any number of threads.
//! - [`io`]: reading files, with errors that name the file. [`report`], beside it: text
//!   reports at fixed precision, CSV and SVG figures.
//! - [`pipeline`]: the calibration of files of every kind and of views on a tree (the choices,
//!   the calibration, the held-out sets, the cross-validation, the report), in one call as
//!   the command runs it, for the command line and the Python package alike.
//!
//! The PUMA 560 of the paper at its "ready" pose:
//!
//! ```
//! use robocal::kinematics::Chain;
//! use robocal::model::RobotModel;
//!
//! let puma = RobotModel::preset("puma560").unwrap();
//! let chain = Chain::new(&puma);
//! let nominal = chain.with_errors(&vec![0.0; chain.params().len()]);
//! let ready = [0.0, 90f64.to_radians(), -90f64.to_radians(), 0.0, 0.0, 0.0];
//! let tool = nominal.position(&ready); // mm
//! assert!((tool - nalgebra::Vector3::new(70.3, -150.05, 1013.6)).norm() < 1e-9);
//! ```
//!
//! A calibration from the example's marker file, judged on poses it did not see (what
//! `robocal calibrate --model puma560 --data examples/puma560-measurements.csv --validate
//! examples/puma560-validation.csv --marker 50,0,150 --marker=-40,60,120` prints): every kind
//! of file (markers, a probe's poses, distances, contacts, coordinates, camera views) is read
//! into [`KindData`] and calibrated by [`calibrate_kinds`], one pipeline for all.
//!
//! ```
//! use nalgebra::Vector3;
//! use robocal::{KindData, KindOptions, RobotModel, calibrate_kinds};
//!
//! let model = RobotModel::preset("puma560").ok_or("no preset puma560")?;
//! let read = |path: &str| KindData::from_csv_str(&std::fs::read_to_string(path)?, &model, None)
//!     .map_err(Box::<dyn std::error::Error>::from);
//! let (training, held_out) =
//!     (read("examples/puma560-measurements.csv")?, read("examples/puma560-validation.csv")?);
//! let markers = vec![Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)];
//! let calibration = calibrate_kinds(&model, &training, &KindOptions { markers, ..KindOptions::default() })?;
//! // The RMS of the held-out marker positions' errors, before and after: 2.21 and 0.12 mm.
//! let (before, after) = calibration.score(&held_out)?.markers.ok_or("markers measured")?;
//! assert!(before > 2.0 && after < 0.13, "held out: {before} mm before, {after} mm after");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Units inside the library are millimetres and radians; degrees appear only at the edges.
//! The core (model, kinematics, estimation, simulation, calibration) does no I/O: files
//! are read and written only in [`io`].

#![warn(missing_docs)]

pub mod calibration;
pub mod design;
pub mod error;
pub mod estimation;
pub mod io;
pub mod kinematics;
pub mod limits;
mod linalg;
pub mod model;
pub mod pipeline;
pub mod report;
pub mod simulation;
pub mod table;

// The one calibration, at the crate root: any kind of file read into a [`KindData`],
// calibrated by [`calibrate_kinds`] under [`KindOptions`] (a tree's views, [`TreeData`], by
// [`calibrate_tree`] under the same options), the one result [`Calibration`] of either,
// held-out data scored by [`Calibration::score`] into a [`Score`]; [`evaluate_kinds`] scores
// a model as it stands.
pub use calibration::kinds::{
    Calibration, KindCalibration, KindData, KindOptions, Score, calibrate_kinds, evaluate_kinds,
};
pub use calibration::tree::{TreeCalibration, TreeData, calibrate_tree};
pub use calibration::{CalibrationError, DataKind};
pub use estimation::Estimator;
pub use model::{RobotModel, RobotTree};
