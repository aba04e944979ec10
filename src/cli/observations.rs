//! `robocal calibrate-observations`: a robot calibrated from distances, plane contacts,
//! partial coordinates, cameras' views and marker positions ([`robocal::calibration::kinds`]); every file read and the fit made
//! before anything is written.

use super::request::{CalibrateObservationsRequest, Method};
use anyhow::{Context, Result, bail};
use robocal::calibration::Kinds;
use robocal::calibration::kinds::{KindData, KindOptions, Observation, Score};
use robocal::estimation::RefineOptions;
use robocal::io;
use robocal::model::{Joint, RobotModel};
use robocal::report::residuals::ResidualSet;
use std::path::Path;

/// Calibrate, print the report, write the files asked for.
pub fn run(request: &CalibrateObservationsRequest) -> Result<()> {
    let robot = super::calibrate::load_model(&request.model)?;
    let model = robot.model.clone();
    let sessions = (request.data.iter())
        .map(|path| Ok((path.display().to_string(), read(path, &model, request)?)))
        .collect::<Result<Vec<_>>>()?;
    let data = sessions.iter().fold(KindData::default(), |data, (_, file)| data.join(file));
    check_and_warn(request, &data)?;
    let options = kind_options(request, &model)?;
    let held_out = (request.validate.iter())
        .map(|path| Ok((path.display().to_string(), read(path, &model, request)?)))
        .collect::<Result<Vec<_>>>()?;
    let choices =
        robocal::calibration::Choices::from_flags(request.auto_prior.clone(), request.select, request.folds);
    let fitting = robocal::pipeline::Fitting::new(request.method == Method::Feasible, choices, request.folds);
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
            page: &|figures| report.page(&format!("Calibration of {}", report.model), &text, figures),
            sets: residual_sets(&report.sets, &sessions, &held_out, &model.joints)?,
            joints: &model.joints,
            prior_scale: report.prior_scale.as_ref(),
            selection: report.selection.as_ref(),
        };
        super::write_residual_files(&request.report, content, &mut outputs)?;
    }
    if let Some(path) = &request.out_model {
        outputs.add(path, robocal::model::to_toml_with_markers(&c.calibrated, &c.marker_positions()));
    }
    if let (Some(path), Some(urdf)) = (&request.out_urdf, &robot.urdf) {
        let text =
            robocal::model::to_urdf_string(&urdf.text, &urdf.base_link, &urdf.tip_link, &c.calibrated)?;
        outputs.add(path, robocal::model::with_urdf_markers(&text, &c.marker_positions())?);
    }
    super::commit(outputs)
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
             their own, always estimated; a camera's mounting is the set-up's): it changes nothing"
        );
    }
    Ok(())
}

/// The options of the observation calibration `request` asks for on `model`.
fn kind_options(request: &CalibrateObservationsRequest, model: &RobotModel) -> Result<KindOptions> {
    Ok(KindOptions {
        per_session: request.per_session.clone(),
        prior: request.prior.clone(),
        loss: request.loss,
        gauge: request.gauge.clone(),
        estimator: request.method.estimator(),
        joint_noise: super::joint_covariance(&model.name, &model.joints, request.joint_sigma_deg.as_deref())?,
        joints: request.joints.clone(),
        estimate_tool: request.estimate_tool,
        tool: request.tool.unwrap_or_else(|| model.tool_point_in_marker_frame()),
        markers: request.markers.clone(),
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
    let files = training().chain(held_out.chunks(1).map(super::by_name)).chain(training());
    (files.zip(scores))
        .map(|(files, (name, score))| {
            ResidualSet::of_observations(name, score, &files, joints).map_err(anyhow::Error::msg)
        })
        .collect()
}

/// One observation file.
fn read(path: &Path, model: &RobotModel, request: &CalibrateObservationsRequest) -> Result<KindData> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let data =
        KindData::from_csv_str(&text, model, request.units).with_context(|| path.display().to_string())?;
    super::status(format!("{}: read {}", path.display(), data.summary()));
    Ok(data.named(&super::request::session_name(path)))
}
