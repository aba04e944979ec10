//! `robocal accuracy`: the calibrated robot's predicted accuracy over a pose file or a grid of
//! its joint ranges, from the covariance `calibrate --out-model` writes beside the model; and
//! that sidecar's writing.

use anyhow::{Context, Result, bail};
use clap::Args;
use robocal::design::accuracy::{AccuracyModel, ParameterCovariance, joint_grid};
use robocal::model::ModelRef;
use robocal::report;
use std::path::{Path, PathBuf};

/// The flags of `robocal accuracy`.
#[derive(Args, Debug)]
pub struct AccuracyArgs {
    /// The calibrated model (a model TOML file as `calibrate --out-model` writes it).
    #[arg(long)]
    pub model: String,
    /// Its parameter covariance (default: `<model>.covariance.json`, which `calibrate
    /// --out-model` writes beside it).
    #[arg(long)]
    pub covariance: Option<PathBuf>,
    /// The poses to predict at: a pose file (CSV with the model's joint columns).
    #[arg(long, conflicts_with = "grid")]
    pub poses: Option<PathBuf>,
    /// Or a grid over the joint ranges: this many values of each joint but the wrist's.
    #[arg(long)]
    pub grid: Option<usize>,
    /// The wrist joints of --grid, held at the middle of their ranges.
    #[arg(long, default_value_t = 3)]
    pub wrist: usize,
    /// The calibration's poses (a measurement or pose file), marked on the figures.
    #[arg(long)]
    pub calibration_poses: Option<PathBuf>,
    /// Write the predictions here (CSV); without it they go to standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the figures (SVG) into this folder: a map over the x-y plane and the distribution
    /// over each joint's range.
    #[arg(long)]
    pub figures: Option<PathBuf>,
}

/// The sidecar of a calibrated model written to `model`: `<model>.covariance.json`.
pub(super) fn covariance_path(model: &Path) -> PathBuf {
    let mut name = model.as_os_str().to_owned();
    name.push(".covariance.json");
    PathBuf::from(name)
}

/// Whether `path` names a regular file to write (or one to create), not `-` or a device.
pub(super) fn has_a_sidecar(path: &Path) -> bool {
    path != Path::new("-") && std::fs::metadata(path).map_or(true, |m| m.is_file())
}

/// Predict; write the CSV, the summary and the figures.
pub fn run(args: &AccuracyArgs) -> Result<()> {
    let model = robocal::io::load_model(&ModelRef::named(&args.model))?;
    let path = args.covariance.clone().unwrap_or_else(|| covariance_path(Path::new(&args.model)));
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!("{}: the model's covariance (calibrate --out-model writes it)", path.display())
    })?;
    let covariance = ParameterCovariance::from_json(&text).with_context(|| path.display().to_string())?;
    let predictor = AccuracyModel::new(&model, &covariance).with_context(|| path.display().to_string())?;
    let (poses, source) = match (&args.poses, args.grid) {
        (Some(file), _) => (robocal::io::load_poses(file, &model, None)?, file.display().to_string()),
        (None, Some(n)) if (1..=1000).contains(&n) => {
            let poses = joint_grid(&model, n, args.wrist);
            if poses.len() > 10_000_000 {
                bail!(
                    "--grid {n}: {} poses, more than 10 million: a coarser grid or a larger --wrist",
                    poses.len()
                );
            }
            (poses, format!("a grid of {n} values per joint"))
        }
        (None, Some(n)) => bail!("--grid: 1 to 1000 values per joint, got {n}"),
        (None, None) => bail!("give --poses FILE or --grid N"),
    };
    let predicted = predictor.map(&poses);
    let points: Vec<report::accuracy::Point<'_>> =
        poses.iter().zip(&predicted).map(|(q, (p, s))| (q.as_slice(), *p, *s)).collect();
    let summary = report::accuracy::text(&source, predictor.parameters(), covariance.floor_mm, &points);
    let csv = report::accuracy::csv(&model, &points);
    let mut outputs = robocal::io::Outputs::new();
    if let Some(folder) = &args.figures {
        let calibration = match &args.calibration_poses {
            Some(file) => {
                let q = robocal::io::load_poses(file, &model, None)?;
                let at = predictor.map(&q);
                q.into_iter().zip(at).map(|(q, (p, _))| (q, p)).collect()
            }
            None => Vec::new(),
        };
        outputs.add_folder(folder, &report::accuracy::figures(&model, &points, &calibration)?);
    }
    match &args.out {
        Some(path) => {
            outputs.add(path, csv);
            super::commit(outputs)?;
            print!("{summary}");
        }
        None => {
            super::commit(outputs)?;
            super::status_text(&summary);
            print!("{csv}");
        }
    }
    Ok(())
}
