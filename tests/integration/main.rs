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

/// A marker or 6-DOF probe file `text` for `model`, read as `robocal calibrate` reads it, the
/// rows' sigmas from `noise`'s measurement part where it has one (a per-axis noise's x sigma for
/// the positions, its rx sigma for the orientations; a per-point noise is a device's and goes
/// through [`KindData::with_device`](robocal::calibration::kinds::KindData::with_device)).
pub(crate) fn marker_data(
    text: &str,
    model: &robocal::model::RobotModel,
    noise: Option<&robocal::estimation::NoiseModel>,
) -> robocal::calibration::kinds::KindData {
    use robocal::calibration::kinds::{KindData, RowSigmaDefaults};
    use robocal::estimation::MeasurementNoise;
    let sigmas = match noise.map(|n| &n.measurement) {
        Some(MeasurementNoise::PerAxis(s)) => RowSigmaDefaults::positive(Some(s[0]), Some(s[3])),
        _ => RowSigmaDefaults::default(),
    };
    KindData::from_csv_str_with(text, model, None, sigmas).unwrap()
}

/// The options of a marker calibration of `model` as `robocal calibrate` sets them: the
/// `estimator`, the joint noise of `noise` (none: the joints exact), the nominal `markers` (mm,
/// the marker frame), the tool point the model's.
pub(crate) fn marker_options(
    model: &robocal::model::RobotModel,
    estimator: robocal::estimation::Estimator,
    noise: Option<&robocal::estimation::NoiseModel>,
    markers: &[nalgebra::Vector3<f64>],
) -> robocal::calibration::kinds::KindOptions {
    robocal::calibration::kinds::KindOptions {
        estimator,
        joint_noise: noise.map(|n| n.joint.clone()),
        tool: model.tool_point_in_marker_frame(),
        markers: markers.to_vec(),
        ..Default::default()
    }
}

/// Writes to `to` the marker file `from` with its first marker's columns only (`j1..j6,x1,y1,z1`
/// of a six-joint arm's file).
pub(crate) fn write_first_marker_only(from: &str, to: &std::path::Path) {
    let text = std::fs::read_to_string(from).unwrap();
    let kept: Vec<String> = (text.lines())
        .map(|l| {
            if l.starts_with('#') {
                l.to_string()
            } else {
                l.split(',').take(9).collect::<Vec<_>>().join(",")
            }
        })
        .collect();
    std::fs::write(to, kept.join("\n") + "\n").unwrap();
}
