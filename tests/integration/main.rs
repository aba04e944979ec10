//! robocal's integration tests, gathered in one test binary.

mod calibration;
mod cli;
mod estimation;
mod fgls;
mod kinematics;
mod model_files;
mod noise;
mod observability;
mod planning;
mod repeatability;
mod replication;
mod simulation;
mod urdf;
