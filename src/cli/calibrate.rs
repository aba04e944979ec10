//! `robocal calibrate`, one step per function: load the model, load the data, check the flags
//! against the files, build the options, run, validate, write. Everything is read and
//! computed before anything is written.

use super::request::{CalibrateRequest, Method, NoiseSource};
use super::{ReportContent, check_marker_count, noise_model, write_report_files};
use anyhow::{Context, Result, bail};
use robocal::calibration::{self, Calibration, Measurements, Options};
use robocal::estimation::NoiseModel;
use robocal::estimation::RefineOptions;
use robocal::io::{self, UrdfChain};
use robocal::model::{ModelRef, RobotModel};
use robocal::report::calibration::CalibrationReport;
use std::path::Path;

/// The nominal robot, with the text and links of its URDF file to write it back.
pub(super) struct Robot {
    /// The model, carrying the payload if one is given.
    pub(super) model: RobotModel,
    /// The model's own payload (its file's), not this session's `--payload-kg`: the
    /// calibrated model is written with it.
    own_payload: Option<robocal::model::Payload>,
    /// A URDF model's file, to write the calibrated URDF from.
    pub(super) urdf: Option<UrdfChain>,
}

impl Robot {
    /// The `calibrated` robot as `--out-model` writes it: as it is, without the payload of
    /// this session (`model`'s `--payload-kg`), with the model file's own (its estimated mass
    /// if the file carries one).
    pub(super) fn as_written(&self, calibrated: &RobotModel, model: &ModelRef) -> RobotModel {
        let payload = if model.payload.is_some() { self.own_payload } else { calibrated.payload };
        RobotModel { payload, ..calibrated.clone() }
    }
}

/// The measurements to calibrate on and the held-out files, by name.
struct Data {
    /// The calibration data (its markers chosen by `--markers`).
    fit: Measurements,
    /// The highest marker number of the file, whether fitted or not.
    highest_marker: usize,
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
    let asked = options(request, &robot.model, &data.fit)?;
    let marker_request = robocal::pipeline::MarkerRequest {
        data: request.data.display().to_string(),
        options: asked,
        choices: calibration::Choices::from_flags(request.auto_prior.clone(), request.select, request.folds),
        feasible: request.method == Method::Feasible,
        held_out: held_out_noise(request, &robot.model, data.held_out)?,
        folds: request.folds,
    };
    let outcome = robocal::pipeline::calibrate_markers(&robot.model, &data.fit, &marker_request)
        .map_err(|e| marker_error(e, request, &marker_request.choices))?;
    let (report, result) = (outcome.report, outcome.calibration);
    let text = report.text();
    let [json, poses, html] = super::report_outputs(&request.report);
    super::show_report(&text, &[json, poses, html, request.out_model.as_ref(), request.out_urdf.as_ref()]);
    write(request, &robot, &report, &result, &text)
}

/// A calibration's error with what it concerns: a name that matches no parameter, or a bad
/// prior, is the flags' (`--params`, `--hold`, `--keep`, `--prior`, or the noise file's
/// `[prior]`); anything else the data's.
fn in_context(e: calibration::CalibrationError, request: &CalibrateRequest) -> anyhow::Error {
    use calibration::CalibrationError::{Prior, Selection};
    let context = match (&e, &request.noise) {
        (Selection(_), _) => "--params, --hold or --keep".to_string(),
        (Prior(_), Some(NoiseSource::File(path))) => {
            format!("--prior or the [prior] table of {}", path.display())
        }
        (Prior(_), _) => "--prior".to_string(),
        _ => request.data.display().to_string(),
    };
    anyhow::Error::new(e).context(context)
}

/// The pipeline's error as the command says it: a choice's with the choices and the data, the
/// calibration's by what it concerns ([`in_context`]), any other as it is.
fn marker_error(
    e: robocal::pipeline::MarkerError,
    request: &CalibrateRequest,
    choices: &calibration::Choices,
) -> anyhow::Error {
    use robocal::pipeline::MarkerError::{Accuracy, Calibration, Choice, CrossValidation, Validation};
    match e {
        Choice(e) => {
            let words = robocal::pipeline::choices_in_words(choices).join(", ");
            anyhow::Error::new(e).context(format!("{words}: {}", request.data.display()))
        }
        Calibration(e) => in_context(e, request),
        Validation(e) | CrossValidation(e) => e.into(),
        Accuracy(e) => e.into(),
    }
}

/// Load the model: a preset, a model file, or a URDF chain, with the payload if one is given.
pub(super) fn load_model(model: &ModelRef) -> Result<Robot> {
    let (own, urdf) = if model.is_urdf() {
        let chain =
            io::load_urdf(Path::new(&model.name), model.base_link.as_deref(), model.tip_link.as_deref())?;
        (chain.model.clone(), Some(chain))
    } else {
        (io::load_model(&ModelRef { payload: None, ..model.clone() })?, None)
    };
    let carrying = match &model.payload {
        Some(payload) => own.with_payload(payload),
        None => own.clone(),
    };
    Ok(Robot { model: carrying, own_payload: own.payload, urdf })
}

/// Load the measurements and the held-out files.
fn load_data(request: &CalibrateRequest, model: &RobotModel) -> Result<Data> {
    let mut fit = io::load_measurements(&request.data, model, request.units)?;
    if !fit.ignored.is_empty() {
        super::status(format_args!(
            "note: {}: ignoring columns {}",
            request.data.display(),
            fit.ignored.join(", ")
        ));
    }
    let highest_marker = fit.marker_ids.iter().copied().max().unwrap_or(0);
    if let Some(ids) = &request.marker_ids {
        fit = fit.with_markers(ids).with_context(|| {
            format!("--markers {ids:?}: {} has markers {:?}", request.data.display(), fit.marker_ids)
        })?;
        if let Some(missing) = ids.iter().find(|id| !fit.marker_ids.contains(id)) {
            bail!(
                "--markers: {} has no marker {missing} (it has {:?})",
                request.data.display(),
                fit.marker_ids
            );
        }
    }
    let held_out = request
        .validate
        .iter()
        .map(|path| {
            let all = io::load_measurements(path, model, request.units)?;
            let scored = all.with_markers(&fit.marker_ids).with_context(|| {
                format!(
                    "{}: none of the fitted markers {:?} (it has {:?})",
                    path.display(),
                    fit.marker_ids,
                    all.marker_ids
                )
            })?;
            Ok((path.display().to_string(), scored))
        })
        .collect::<Result<_>>()?;
    Ok(Data { fit, highest_marker, held_out })
}

/// The rules that need the files' contents: the markers against the data, the held-out files'
/// markers, the folds against the poses. (The joint sigmas are counted by [`noise_model`].)
fn check_against_the_files(request: &CalibrateRequest, data: &Data) -> Result<()> {
    check_marker_count(request.markers.len(), &request.data, data.highest_marker)?;
    super::warn_unplaced_fixed_markers(!request.estimate_markers, request.markers.len(), data.highest_marker);
    if let Some((name, _)) =
        data.held_out.iter().find(|(_, d)| d.orientations.is_some() != data.fit.orientations.is_some())
    {
        bail!("{name}: orientation columns must be as in {}", request.data.display());
    }
    if let Some(k) = request.folds.filter(|&k| k > data.fit.len()) {
        bail!("--folds {k}: expected 2 to {} (the number of poses)", data.fit.len());
    }
    Ok(())
}

/// The library's options: the noise (from its file or the flags), the estimator, the
/// parameters, the markers and the iterations.
fn options(request: &CalibrateRequest, model: &RobotModel, data: &Measurements) -> Result<Options> {
    let noise = noise_for(request.noise.as_ref(), model, data)?;
    // A noise file's [prior] table, then the flags'.
    let mut prior = match &request.noise {
        Some(NoiseSource::File(path)) => io::load_noise(path, model)?.prior,
        _ => Vec::new(),
    };
    prior.extend(request.prior.iter().cloned());
    // The k-th --marker is marker k of the file; the fitted ones are picked by number.
    let markers =
        data.marker_ids.iter().map(|&id| request.markers.get(id - 1).copied().unwrap_or_default()).collect();
    Ok(Options {
        estimator: request.method.estimator(),
        noise,
        joints: request.joints.clone(),
        estimate_base: request.estimate_base,
        estimate_markers: request.estimate_markers,
        markers,
        prior,
        loss: request.loss,
        refine: RefineOptions { max_iterations: request.iterations, ..RefineOptions::default() },
        gauge: robocal::calibration::Gauge { hold: request.hold.clone(), keep: request.keep.clone() },
    })
}

/// The noise of `source` at the poses of `data`: the flags' everywhere, a noise file's device
/// at each measured marker.
pub(super) fn noise_for(
    source: Option<&NoiseSource>,
    model: &RobotModel,
    data: &Measurements,
) -> Result<Option<NoiseModel>> {
    Ok(match source {
        None => None,
        Some(NoiseSource::Flags(flags)) => Some(noise_model(model, flags)?),
        Some(NoiseSource::File(path)) => {
            let spec = io::load_noise(path, model)?;
            let noise = calibration::noise_from_spec(&spec, data)
                .with_context(|| format!("{}: the device's covariance", path.display()))?;
            Some(noise)
        }
    })
}

/// Each held-out file with the noise at its poses (the flags' or a noise file's device). They
/// are scored only: no choice is made on them.
fn held_out_noise(
    request: &CalibrateRequest,
    model: &RobotModel,
    held_out: Vec<(String, Measurements)>,
) -> Result<Vec<(String, Measurements, Option<NoiseModel>)>> {
    held_out
        .into_iter()
        .map(|(name, d)| {
            let noise = noise_for(request.noise.as_ref(), model, &d)?;
            Ok((name, d, noise))
        })
        .collect()
}

/// Write the JSON report, the poses, the figures, the page, the calibrated model and the
/// calibrated URDF, as asked: all of them or none.
fn write(
    request: &CalibrateRequest,
    robot: &Robot,
    report: &CalibrationReport,
    result: &Calibration,
    text: &str,
) -> Result<()> {
    let title = format!("calibration of {} from {}", report.model, report.data);
    let json = super::json_if_asked(&request.report, report)?;
    let mut outputs = io::Outputs::new();
    let mut extra_figures = Vec::new();
    if request.report.figures.is_some() || request.report.html.is_some() {
        // The choices made from the data: the prior's scale curve, the selection's path.
        if let Some(scale) = &report.prior_scale {
            extra_figures.push(robocal::report::figures::prior_scale_figure(scale)?);
        }
        if let Some(selection) = &report.selection {
            extra_figures.push(robocal::report::figures::selection_figure(selection)?);
        }
        let sets: Vec<_> = report.sets.iter().collect();
        extra_figures.extend(robocal::report::figures::torque_figures(&sets, &result.calibrated)?);
    }
    // With --folds, the training poses held out in their folds after the sets scored.
    let cv = report.cross_validation.as_ref().and_then(|cv| cv.poses.clone());
    let sets: Vec<_> = report.sets.iter().cloned().chain(cv).collect();
    let content = ReportContent {
        title: &title,
        text,
        json,
        sets: &sets,
        joints: &result.registered.joints,
        extra_figures,
        calibration: Some(report),
    };
    write_report_files(&request.report, content, &mut outputs)?;
    let markers = result.marker_positions();
    if let Some(path) = &request.out_model {
        let calibrated = robot.as_written(&result.calibrated, &request.model);
        outputs.add(path, robocal::model::to_toml_with_markers(&calibrated, &markers));
        if super::accuracy::has_a_sidecar(path) {
            let sidecar = super::accuracy::covariance_sidecar(&report.sets, result);
            outputs.add(super::accuracy::covariance_path(path), sidecar);
        }
    }
    if let (Some(path), Some(urdf)) = (&request.out_urdf, &robot.urdf) {
        let text =
            robocal::model::to_urdf_string(&urdf.text, &urdf.base_link, &urdf.tip_link, &result.calibrated)?;
        outputs.add(path, robocal::model::with_urdf_markers(&text, &markers)?);
    }
    super::commit(outputs)
}
