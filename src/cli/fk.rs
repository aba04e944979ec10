//! `robocal fk`: the tool pose of a model at given joint values.

use super::args::FkArgs;
use super::from_flag_unit;
use anyhow::{Result, bail};
use robocal::kinematics::Chain;
use robocal::model::RobotModel;
use robocal::{io, report};

/// Print the tool pose, warning about joints outside their limits.
pub fn run(args: &FkArgs) -> Result<()> {
    let model = io::load_model(&args.model.model_ref()?)?;
    let q = joint_values(&model, &args.q.0)?;
    for joint in model.joints_outside_limits(&q) {
        eprintln!("warning: joint {joint} lies outside its limits");
    }
    let pose = Chain::new(&model).with_errors(&vec![0.0; model.params().len()]).pose(&q);
    print!("{}", report::tool_pose(&model, &q, &pose));
    Ok(())
}

/// `--q` in the model's units (radians; mm), one value per joint of `model`.
fn joint_values(model: &RobotModel, values: &[f64]) -> Result<Vec<f64>> {
    if values.len() != model.dof() {
        bail!(
            "--q: {} has {} joints, got {} values (degrees for revolute joints, mm for prismatic)",
            model.name,
            model.dof(),
            values.len()
        );
    }
    Ok(model.joints.iter().zip(values).map(|(joint, &v)| from_flag_unit(joint.kind, v)).collect())
}
