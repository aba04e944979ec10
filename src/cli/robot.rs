//! The nominal robot a command loads: a preset, a model file or a URDF chain, with this
//! session's payload, and what is needed to write it back calibrated.

use anyhow::Result;
use robocal::io::{self, UrdfChain};
use robocal::model::{ModelRef, RobotModel};
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
