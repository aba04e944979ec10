//! robocal's integration tests, gathered in one test binary.

mod calibration;
mod camera;
mod cli;
mod compliance;
mod estimation;
mod fgls;
mod fuzz;
mod instruments;
mod kinds;
mod kinds_markers;
mod kinematics;
mod layering;
mod model_files;
mod noise;
mod observability;
mod planning;
mod prior;
mod reliability;
mod repeatability;
mod replication;
mod report;
mod robust;
mod selection;
mod simulation;
mod tree;
mod urdf;
