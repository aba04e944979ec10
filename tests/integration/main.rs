//! robocal's integration tests, gathered in one test binary.

mod accuracy;
mod calibration;
mod camera;
mod choice;
mod cli;
mod compensate;
mod compliance;
mod conventions;
mod estimation;
mod evidence;
mod export;
mod features;
mod fgls;
mod figures;
mod fuzz;
mod instruments;
mod kinds;
mod kinds_fgls;
mod kinds_markers;
mod kinematics;
mod layering;
mod model_files;
mod nested;
mod noise;
mod noise_check;
mod observability;
mod overfit;
mod planning;
mod plausibility;
mod presets;
mod prior;
mod reliability;
mod repeatability;
mod replication;
mod report;
mod residuals;
mod robust;
mod selection;
mod selection_physics;
mod sessions;
mod shards;
mod simulation;
mod solver;
mod tree;
mod urdf;

/// The RMS before and after of the verdict row of an observation report (`label  count  b ->
/// a unit  max  flagged`): the first `b -> a` of `row`.
pub(crate) fn verdict_rms(row: &str) -> (f64, f64) {
    let cells: Vec<&str> = row.split_whitespace().collect();
    let arrow = cells.iter().position(|&c| c == "->").unwrap_or_else(|| panic!("no `->` in {row}"));
    let number = |c: &str| c.parse::<f64>().unwrap_or_else(|_| panic!("`{c}` in {row}"));
    (number(cells[arrow - 1]), number(cells[arrow + 1]))
}
