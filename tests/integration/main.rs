//! robocal's integration tests, gathered in one test binary.

mod kinematics;
mod model_files;
