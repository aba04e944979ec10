//! robocal's integration tests, gathered in one test binary.

mod calibration;
mod cli;
mod estimation;
mod kinematics;
mod model_files;
mod observability;
mod planning;
mod simulation;
mod urdf;
