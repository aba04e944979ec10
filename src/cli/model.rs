//! `robocal model`: list the presets, show a model, write it as URDF or as the UR driver's
//! kinematics file.

use super::args::ModelCommand;
use anyhow::{Context, Result};
use robocal::io;
use robocal::model::{PRESETS, Placement, RobotModel, UrdfOptions, to_ur_kinematics, to_urdf};

/// Print the presets, or a model as TOML.
pub fn run(command: &ModelCommand) -> Result<()> {
    match command {
        ModelCommand::Show { model, links } => {
            let model = links.model_ref(model)?;
            let read = io::load_model(&model)?;
            if model.is_urdf() {
                println!("# the chain of {}: {}", model.name, read.description);
            }
            print!("{}", read.to_toml_string());
        }
        ModelCommand::Urdf { model, links, urdf_standard, out } => {
            let read = io::load_model(&links.model_ref(model)?)?;
            for joint in read.joints.iter().filter(|j| j.compliance < 0.0) {
                eprintln!(
                    "warning: {}: a negative compliance ({:.3e}), which no real joint has: it absorbs something else (geometry, play, masses); written as estimated",
                    joint.name, joint.compliance
                );
            }
            let mut exported = to_urdf(&read, UrdfOptions { standard: *urdf_standard });
            if let Some(sidecar) = exported.sidecar.as_mut() {
                sidecar.push_str(&covariance_table(std::path::Path::new(model))?);
            }
            let mut outputs = io::Outputs::new();
            match out {
                Some(path) => {
                    outputs.add(path, exported.urdf);
                    if let Some(sidecar) = exported.sidecar {
                        outputs.add(path.with_extension("extras.toml"), sidecar);
                    }
                    super::commit(outputs)?;
                }
                None => {
                    print!("{}", exported.urdf);
                    if let Some(sidecar) = exported.sidecar {
                        eprint!("{sidecar}");
                    }
                }
            }
        }
        ModelCommand::UrKinematics { model, links, out } => {
            let read = io::load_model(&links.model_ref(model)?)?;
            let (yaml, tcp) = to_ur_kinematics(&read).with_context(|| model.clone())?;
            match out {
                Some(path) => {
                    let mut outputs = io::Outputs::new();
                    outputs.add(path, yaml);
                    super::commit(outputs)?;
                }
                None => print!("{yaml}"),
            }
            if tcp.translation.vector.norm() > 1e-9 || tcp.rotation.angle() > 1e-12 {
                let p = Placement::from_isometry(&tcp);
                eprintln!(
                    "the tool is not in the file: set the TCP to xyz ({:.4}, {:.4}, {:.4}) mm, rpy ({:.6}, {:.6}, {:.6}) deg",
                    p.xyz.x,
                    p.xyz.y,
                    p.xyz.z,
                    p.rpy.x.to_degrees(),
                    p.rpy.y.to_degrees(),
                    p.rpy.z.to_degrees()
                );
            }
        }
        ModelCommand::List => {
            for (name, _) in PRESETS {
                let model = RobotModel::preset(name).expect("presets are valid");
                println!("{name:<15} {} joints  {}", model.dof(), model.description);
            }
        }
    }
    Ok(())
}

/// The calibration's parameter covariance beside the model file `model`
/// (`<model>.covariance.json`, as `calibrate --out-model` writes it), as a TOML table for the
/// URDF's sidecar; empty when there is none.
fn covariance_table(model: &std::path::Path) -> Result<String> {
    let path = super::accuracy::covariance_path(model);
    if !path.is_file() {
        return Ok(String::new());
    }
    let text = std::fs::read_to_string(&path).with_context(|| format!("{}: cannot read", path.display()))?;
    let c = robocal::design::accuracy::ParameterCovariance::from_json(&text)
        .with_context(|| path.display().to_string())?;
    let names: Vec<String> = c.names.iter().map(|n| format!("{n:?}")).collect();
    let rows: Vec<String> = (c.covariance.iter())
        .map(|r| format!("  [{}]", r.iter().map(|v| format!("{v:?}")).collect::<Vec<_>>().join(", ")))
        .collect();
    Ok(format!(
        "\n# the calibration's parameter covariance (mm, rad; the names' order), from {}\n[covariance]\nnames = [{}]\nfloor_mm = {:?}\nmatrix = [\n{}\n]\n",
        path.display(),
        names.join(", "),
        c.floor_mm,
        rows.join(",\n")
    ))
}
