//! `robocal calibrate`: a robot calibrated from marker positions, a probe's poses, distances,
//! plane contacts, partial coordinates and cameras' views ([`robocal::calibration::kinds`]); every file read and the fit made
//! before anything is written.

use super::request::{CalibrateObservationsRequest, Method};
use anyhow::{Context, Result, bail};
use robocal::calibration::Kinds;
use robocal::calibration::kinds::{KindData, KindOptions, Observation, RowSigmaDefaults, Score};
use robocal::estimation::{Device, Estimator, RefineOptions};
use robocal::io;
use robocal::model::{Joint, RobotModel};
use robocal::report::residuals::ResidualSet;
use robocal::table::Units;
use std::path::Path;

/// Calibrate, print the report, write the files asked for.
pub fn run(request: &CalibrateObservationsRequest) -> Result<()> {
    let robot = super::robot::load_model(&request.model)?;
    let model = robot.model.clone();
    let noise =
        Noise::of(request.noise.as_deref(), request.joint_sigma_deg.as_deref(), request.sigmas, &model)?;
    let (sigmas, device) = (noise.sigmas, noise.device.clone());
    let read = |path: &Path| read(path, &model, request.units, sigmas, device.as_ref());
    let sessions = (request.data.iter())
        .map(|path| Ok((path.display().to_string(), read(path)?)))
        .collect::<Result<Vec<_>>>()?;
    let method;
    let sessions = {
        // The files joined for their checks only, not held while they calibrate; one file as
        // it is (joined alone, it is itself).
        let joined = match sessions.as_slice() {
            [_] => None,
            _ => Some(sessions.iter().fold(KindData::default(), |data, (_, file)| data.join(file))),
        };
        let data = joined.as_ref().unwrap_or(&sessions[0].1);
        let what = format!(
            "calibrating the {} observations at {} poses",
            data.observations.len(),
            data.joints.len()
        );
        method = estimator_for(request, data.noise_given(noise.joint.is_some()))?;
        let needed = data.memory_estimate(model.params().len(), method == Method::Feasible);
        io::check_memory(needed, &what, "calibrate on fewer poses")?;
        check_and_warn(request, data)?;
        if let Some(ids) = &request.marker_ids {
            marker_ids_known(ids, &data.markers())?;
        }
        named_markers(sessions, request.marker_ids.as_deref())?
    };
    let options = kind_options(request, &model, noise, method)?;
    let held_out = (request.validate.iter())
        .map(|path| Ok((path.display().to_string(), read(path)?)))
        .collect::<Result<Vec<_>>>()?;
    let held_out = named_markers(held_out, request.marker_ids.as_deref())?;
    let choices =
        robocal::calibration::Choices::from_flags(request.auto_prior.clone(), request.select, request.folds);
    let fitting = robocal::pipeline::Fitting::new(method == Method::Feasible, choices, request.folds);
    let outcome =
        robocal::pipeline::calibrate_files(&Kinds(&model), &sessions, &held_out, &options, &fitting)?;
    let (c, report) = (outcome.calibration, outcome.report);
    let text = report.text();
    let [json, poses, html] = super::report_outputs(&request.report);
    super::show_report(&text, &[json, poses, html, request.out_model.as_ref(), request.out_urdf.as_ref()]);
    let mut outputs = io::Outputs::new();
    if request.report != super::args::ReportArgs::default() {
        let content = super::ResidualContent {
            json: super::json_if_asked(&request.report, &report)?,
            page: &|figures, sets| {
                report.page(&format!("Calibration of {}", report.model), &text, figures, sets)
            },
            sets: residual_sets(&report.sets, &sessions, &held_out, &model.joints)?,
            joints: &model.joints,
            model: Some(&c.calibrated),
            prior_scale: report.prior_scale.as_ref(),
            selection: report.selection.as_ref(),
        };
        super::write_residual_files(&request.report, content, &mut outputs)?;
    }
    if let Some(path) = &request.out_model {
        let calibrated = robot.as_written(&c.calibrated, &request.model);
        outputs.add(path, robocal::model::to_toml_with_markers(&calibrated, &c.marker_positions()));
        if super::accuracy::has_a_sidecar(path) {
            let sidecar = robocal::pipeline::robot_covariance(&c, report.floor_mm()).to_json();
            outputs.add(super::accuracy::covariance_path(path), sidecar);
        }
    }
    if let (Some(path), Some(urdf)) = (&request.out_urdf, &robot.urdf) {
        let text =
            robocal::model::to_urdf_string(&urdf.text, &urdf.base_link, &urdf.tip_link, &c.calibrated)?;
        outputs.add(path, robocal::model::with_urdf_markers(&text, &c.marker_positions())?);
    }
    super::commit(outputs)
}

/// The estimator of `request` where the noise is `known` (a joint noise or a sigma given) or
/// not: the default wls is ordinary least squares without a noise (every row alike, the
/// residuals' spread their sigma), and a weighted estimator given then is a usage error.
fn estimator_for(request: &CalibrateObservationsRequest, known: bool) -> Result<Method> {
    match request.method {
        Method::Given(estimator) if !known && estimator != Estimator::Ols => match request.estimator_given {
            false => Ok(Method::Given(Estimator::Ols)),
            true => Err(super::UsageError(format!(
                "--estimator {estimator} needs the noise: give --noise or --joint-sigma-deg (and --sigma-mm or a sigma \
                 column), or use --estimator fgls"
            ))
            .into()),
        },
        method => Ok(method),
    }
}

/// The markers given against the files' (an error if more `--marker` than markers), and the
/// warnings of what the data cannot honour: angles read with markers, a fixed tool point
/// nothing measures.
fn check_and_warn(request: &CalibrateObservationsRequest, data: &KindData) -> Result<()> {
    let highest = data.markers().last().map_or(0, |m| m + 1);
    if request.markers.len() > highest {
        bail!(
            "{} --marker given, the files ({}) have {highest} markers: the k-th --marker is marker k of a marker file",
            request.markers.len(),
            request.data.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        );
    }
    let angles = data.observations.iter().any(|o| matches!(o, Observation::Coordinate { axis: 3.., .. }));
    if highest > 0 && angles {
        eprintln!(
            "warning: roll, pitch and yaw fitted with markers are read in the markers' (the tracker's) frame: an \
             inclinometer reading against gravity is not; fit it in a run of its own"
        );
    }
    if !request.estimate_tool && !data.measures_the_tool_point() {
        eprintln!(
            "warning: --fixed-tool holds the tool point, which no observation here measures (markers are points of \
             their own; a camera's mounting is the set-up's): it changes nothing"
        );
    }
    super::warn_unplaced_fixed_markers(!request.estimate_markers, request.markers.len(), highest);
    if !request.estimate_markers && highest == 0 {
        eprintln!("warning: --fixed-markers holds the markers, and no file here has any: it changes nothing");
    }
    if !request.estimate_base && !data.sees_the_base() {
        eprintln!(
            "warning: --fixed-base holds the base, which no observation here sees (only markers and coordinates \
             do): it changes nothing"
        );
    }
    Ok(())
}

/// The files with the markers `--markers` names only (`ids`, numbers from 1: their positions
/// and orientations, [`KindData::with_markers`]), their other observations kept, or as they
/// are; a file with markers, none of them named, is refused.
pub(super) fn named_markers<N: AsRef<Path>>(
    files: Vec<(N, KindData)>,
    ids: Option<&[usize]>,
) -> Result<Vec<(N, KindData)>> {
    let Some(ids) = ids else { return Ok(files) };
    let chosen = |(name, data): (N, KindData)| match data.with_markers(ids) {
        Some(kept) => Ok((name, kept)),
        None => bail!("{}: --markers {ids:?} names none of its markers", name.as_ref().display()),
    };
    files.into_iter().map(chosen).collect()
}

/// `--markers ids` (numbers from 1) against the files' markers `have` (numbers less one): a
/// number that no file's marker has is refused.
pub(super) fn marker_ids_known(ids: &[usize], have: &[usize]) -> Result<()> {
    if let Some(id) = ids.iter().find(|&&id| !have.contains(&(id - 1))) {
        let numbers: Vec<String> = have.iter().map(|m| (m + 1).to_string()).collect();
        bail!(
            "--markers {id}: no data file has marker {id} (x{id}, y{id}, z{id}); their markers: {}",
            if numbers.is_empty() { "none".to_string() } else { numbers.join(", ") }
        );
    }
    Ok(())
}

/// The noise of observation files: the joint noise `Sigma_q` (if given), the sigmas of the rows
/// that give none, a measuring device, and a noise file's prior; from `--noise`, else the flags.
pub(super) struct Noise {
    pub(super) joint: Option<nalgebra::DMatrix<f64>>,
    pub(super) sigmas: RowSigmaDefaults,
    pub(super) device: Option<Device>,
    prior: Vec<robocal::estimation::PriorEntry>,
}

impl Noise {
    /// The noise of the noise file `file` for `model`, else of the flags: `--joint-sigma-deg`'s
    /// `joint_sigma_deg`, and the rows' `sigmas`.
    pub(super) fn of(
        file: Option<&Path>,
        joint_sigma_deg: Option<&[f64]>,
        sigmas: RowSigmaDefaults,
        model: &RobotModel,
    ) -> Result<Self> {
        let Some(path) = file else {
            let joint = super::joint_covariance(&model.name, &model.joints, joint_sigma_deg)?;
            return Ok(Self { joint, sigmas, device: None, prior: Vec::new() });
        };
        let spec = io::load_noise(path, model)?;
        let sigmas = RowSigmaDefaults::of_noise(&spec);
        Ok(Self { joint: Some(spec.joint), sigmas, device: spec.device, prior: spec.prior })
    }
}

/// The options of the observation calibration `request` asks for on `model`, with `noise`
/// (a noise file's prior before `--prior`'s).
fn kind_options(
    request: &CalibrateObservationsRequest,
    model: &RobotModel,
    noise: Noise,
    method: Method,
) -> Result<KindOptions> {
    let mut prior = noise.prior;
    prior.extend(request.prior.iter().cloned());
    Ok(KindOptions {
        per_session: request.per_session.clone(),
        prior,
        loss: request.loss,
        gauge: request.gauge.clone(),
        estimator: method.estimator(),
        joint_noise: noise.joint,
        joints: request.joints.clone(),
        estimate_tool: request.estimate_tool,
        estimate_base: request.estimate_base,
        estimate_markers: request.estimate_markers,
        tool: request.tool.unwrap_or_else(|| model.tool_point_in_marker_frame()),
        markers: request.markers.clone(),
        probe: None,
        refine: RefineOptions { max_iterations: request.iterations, ..RefineOptions::default() },
    })
}

/// The residuals of each scored set (`scores`: the training files', then each held-out
/// file's, then any cross-validation's, each training observation held out in its fold) with
/// their files.
fn residual_sets(
    scores: &[(String, Score)],
    sessions: &[(String, KindData)],
    held_out: &[(String, KindData)],
    joints: &[Joint],
) -> Result<Vec<ResidualSet>> {
    let training = || std::iter::once(super::by_name(sessions));
    // Each held-out file, the held-out files pooled when the report pools them, the folds.
    let pooled = scores.iter().any(|(name, _)| name == robocal::pipeline::HELD_OUT_POOLED);
    let pooled = pooled.then(|| super::by_name(held_out));
    let files = training().chain(held_out.chunks(1).map(super::by_name)).chain(pooled).chain(training());
    (files.zip(scores))
        .map(|(files, (name, score))| {
            ResidualSet::of_observations(name, score, &files, joints).map_err(anyhow::Error::msg)
        })
        .collect()
}

/// One observation file, `sigmas` for its rows that give none, `device`'s covariance at each
/// point measured.
pub(super) fn read(
    path: &Path,
    model: &RobotModel,
    units: Option<Units>,
    sigmas: RowSigmaDefaults,
    device: Option<&Device>,
) -> Result<KindData> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let mut data = KindData::from_csv_str_with(&text, model, units, sigmas)
        .with_context(|| path.display().to_string())?;
    if let Some(device) = device {
        data = data.with_device(|p| device.covariance(p)).with_context(|| path.display().to_string())?;
    }
    super::status(format!("{}: read {}", path.display(), data.summary()));
    Ok(data.named(&super::request::session_name(path)))
}
