//! `robocal calibrate`, one step per function: load the model, load the data, check the flags
//! against the files, build the options, run, validate, write. Everything is read and
//! computed before anything is written.

use super::request::{CalibrateRequest, Method, ModelSource, NoiseSource};
use super::{check_marker_count, noise_model};
use anyhow::{Context, Result, bail};
use robocal::calibration::{self, Calibration, ErrorStats, FeasibleOptions, Measurements, Options};
use robocal::estimation::RefineOptions;
use robocal::io;
use robocal::model::RobotModel;
use robocal::report::calibration::CalibrationReport;

/// The nominal robot, with the text and links of its URDF file to write it back.
struct Robot {
    /// The model.
    model: RobotModel,
    /// A URDF model's file text, base link and tip link.
    urdf: Option<(String, String, String)>,
}

/// The measurements to calibrate on and the held-out files, by name.
struct Data {
    /// The calibration data.
    fit: Measurements,
    /// The held-out files to validate on.
    held_out: Vec<(String, Measurements)>,
}

/// Calibrate, print the report, write the files asked for.
pub fn run(request: &CalibrateRequest) -> Result<()> {
    let robot = load_model(&request.model)?;
    let data = load_data(request, &robot.model)?;
    check_against_the_files(request, &data)?;
    let what = format!("calibrating the {} poses of {}", data.fit.len(), request.data.display());
    io::check_memory(
        data.fit.memory_estimate(robot.model.params().len()),
        &what,
        "calibrate on fewer poses",
    )?;
    let options = options(request, &robot.model, &data.fit)?;
    let result = match request.method {
        Method::Given(_) => calibration::calibrate(&robot.model, &data.fit, &options),
        Method::Feasible => {
            calibration::calibrate_feasible(&robot.model, &data.fit, &options, &FeasibleOptions::default())
        }
    }
    .with_context(|| request.data.display().to_string())?;
    let validation = validate(request, &robot.model, &data, &options, &result)?;
    let name = request.method.name();
    let report = CalibrationReport::new(&result, &request.data.display().to_string(), name, validation);
    print!("{}", report.text());
    write(request, &robot, &report, &result)
}

/// Load the model: a preset, a model file, or a URDF chain.
fn load_model(source: &ModelSource) -> Result<Robot> {
    Ok(match source {
        ModelSource::Named(name) => Robot { model: io::load_model(name)?, urdf: None },
        ModelSource::Urdf { path, base_link, tip_link } => {
            let (model, text) = io::load_urdf(path, base_link, tip_link)?;
            Robot { model, urdf: Some((text, base_link.clone(), tip_link.clone())) }
        }
    })
}

/// Load the measurements and the held-out files.
fn load_data(request: &CalibrateRequest, model: &RobotModel) -> Result<Data> {
    let fit = io::load_measurements(&request.data, model, request.units)?;
    super::warn_outside_limits(
        &request.data,
        model,
        fit.lines.iter().copied().zip(fit.joints.iter().map(Vec::as_slice)),
    );
    if !fit.ignored.is_empty() {
        eprintln!("note: {}: ignoring columns {}", request.data.display(), fit.ignored.join(", "));
    }
    let held_out = request
        .validate
        .iter()
        .map(|path| Ok((path.display().to_string(), io::load_measurements(path, model, request.units)?)))
        .collect::<Result<_>>()?;
    Ok(Data { fit, held_out })
}

/// The rules that need the files' contents: the markers against the data, the held-out files'
/// markers, the folds against the poses. (The joint sigmas are counted by [`noise_model`].)
fn check_against_the_files(request: &CalibrateRequest, data: &Data) -> Result<()> {
    let markers = data.fit.marker_count();
    check_marker_count(request.markers.len(), &request.data, markers)?;
    if data.held_out.iter().any(|(_, d)| d.marker_count() != markers) {
        bail!("the validation files must have the markers of {}", request.data.display());
    }
    if let Some(k) = request.folds.filter(|&k| k > data.fit.len()) {
        bail!("--folds {k}: expected 2 to {} (the number of poses)", data.fit.len());
    }
    Ok(())
}

/// The library's options: the noise (from its file or the flags), the estimator, the
/// parameters, the markers and the iterations.
fn options(request: &CalibrateRequest, model: &RobotModel, data: &Measurements) -> Result<Options> {
    let noise = match &request.noise {
        None => None,
        Some(NoiseSource::Flags(flags)) => Some(noise_model(model, flags)?),
        Some(NoiseSource::File(path)) => {
            let spec = io::load_noise(path, model)?;
            let noise = calibration::noise_from_spec(&spec, data)
                .with_context(|| format!("{}: the device's covariance", path.display()))?;
            Some(noise)
        }
    };
    Ok(Options {
        estimator: request.method.estimator(),
        noise,
        joints: request.joints.clone(),
        estimate_base: request.estimate_base,
        estimate_markers: request.estimate_markers,
        markers: request.markers.clone(),
        refine: RefineOptions { max_iterations: request.iterations, ..RefineOptions::default() },
    })
}

/// Before and after on each held-out file, then the cross-validation if asked for.
fn validate(
    request: &CalibrateRequest,
    model: &RobotModel,
    data: &Data,
    options: &Options,
    result: &Calibration,
) -> Result<Vec<(String, ErrorStats, ErrorStats)>> {
    let mut validation: Vec<_> = data
        .held_out
        .iter()
        .map(|(name, d)| {
            let (before, after) = result.validate(d);
            (name.clone(), before, after)
        })
        .collect();
    if let Some(k) = request.folds {
        let (before, after) = calibration::cross_validate(model, &data.fit, options, k)?;
        validation.push((format!("{k}-fold cross-validation"), before, after));
    }
    Ok(validation)
}

/// Write the JSON report, the calibrated model and the calibrated URDF, as asked: all of them
/// or none.
fn write(
    request: &CalibrateRequest,
    robot: &Robot,
    report: &CalibrationReport,
    result: &Calibration,
) -> Result<()> {
    let mut outputs = io::Outputs::new();
    if let Some(path) = &request.json {
        outputs.add(path, serde_json::to_string_pretty(report)? + "\n");
    }
    if let Some(path) = &request.out_model {
        outputs.add(path, result.calibrated.to_toml_string());
    }
    if let (Some(path), Some((text, base, tip))) = (&request.out_urdf, &robot.urdf) {
        outputs.add(path, robocal::model::to_urdf_string(text, base, tip, &result.calibrated)?);
    }
    Ok(outputs.commit()?)
}
