//! Model files: exact round trip and clear errors.

use proptest::prelude::*;
use robocal::error::FieldError;
use robocal::model::{ModelError, RobotModel};

const PUMA: &str = include_str!("../../presets/puma560.toml");

#[test]
fn puma_preset_reads_with_the_papers_numbers() {
    let model = RobotModel::preset("puma560").unwrap();
    assert_eq!(model.dof(), 6);
    assert_eq!(model.joints[2].d, 150.05);
    assert_eq!(model.joints[3].alpha, 90f64.to_radians());
    assert_eq!(model.joints[1].limits, [-45f64.to_radians(), 225f64.to_radians()]);
}

#[test]
fn written_model_reads_back_exactly() {
    let model = RobotModel::from_toml_str(PUMA).unwrap();
    let text = model.to_toml_string();
    assert_eq!(RobotModel::from_toml_str(&text).unwrap(), model);
    assert!(text.contains("alpha_deg = 90.0"), "degrees are written short:\n{text}");
    assert_eq!(RobotModel::from_toml_str(&text).unwrap().to_toml_string(), text);
}

proptest! {
    /// Any angle read from degrees is written back to the same radians, bit for bit.
    #[test]
    fn any_degrees_round_trip(values in prop::collection::vec(-400.0..400.0f64, 6)) {
        let mut model = RobotModel::from_toml_str(PUMA).unwrap();
        for (joint, deg) in model.joints.iter_mut().zip(&values) {
            joint.alpha = deg.to_radians();
            joint.beta = (deg / 7.0).to_radians();
        }
        prop_assert_eq!(RobotModel::from_toml_str(&model.to_toml_string()).unwrap(), model);
    }
}

fn error_of(text: &str) -> String {
    robocal::error::chain(&RobotModel::from_toml_str(text).unwrap_err())
}

#[test]
fn misspelled_field_is_named_with_its_line() {
    let message = error_of(&PUMA.replacen("a_mm = 431.8", "a_m = 431.8", 1));
    assert!(message.contains("a_m") && message.contains("line"), "{message}");
}

#[test]
fn missing_field_is_named() {
    let message = error_of(&PUMA.replacen("d_mm = 150.05\n", "", 1));
    assert!(message.contains("d_mm"), "{message}");
}

#[test]
fn unknown_convention_says_what_is_allowed() {
    let message = error_of(&PUMA.replace("standard-dh", "dh"));
    assert!(message.contains("standard-dh") && message.contains("modified-dh"), "{message}");
}

#[test]
fn reversed_limits_are_rejected() {
    let err = RobotModel::from_toml_str(&PUMA.replace("[-160.0, 160.0]", "[160.0, -160.0]")).unwrap_err();
    assert_eq!(
        err,
        ModelError::Invalid(FieldError::new("joints[0].limits_deg", "[lower, upper] with lower < upper"))
    );
}

#[test]
fn not_a_number_is_rejected() {
    let message = error_of(&PUMA.replacen("a_mm = 20.3", "a_mm = nan", 1));
    assert_eq!(message, "field `joints[2].a_mm`: a finite number, found NaN");
}

#[test]
fn prismatic_joint_needs_limits_in_mm() {
    let text = PUMA.replacen("type = \"revolute\"", "type = \"prismatic\"", 1);
    assert!(error_of(&text).contains("joints[0].limits_mm"), "{}", error_of(&text));
}

#[test]
fn duplicate_joint_names_are_rejected() {
    let message = error_of(&PUMA.replace("name = \"j2\"", "name = \"j1\""));
    assert!(message.contains("joints[1].name") && message.contains("twice"), "{message}");
}

/// `[[links]]` (kg, mm) and `gravity_m_s2` read, write back exactly, and are checked: one
/// table per joint, masses >= 0; a model without them has no masses and floor gravity.
#[test]
fn link_masses_and_gravity_read_and_write_back() {
    let puma = RobotModel::preset("puma560").unwrap();
    assert!(puma.masses.is_empty());
    assert_eq!(puma.gravity, RobotModel::floor_gravity());
    let links: String =
        (1..=6).map(|i| format!("\n[[links]]\nmass_kg = {i}.5\ncom_mm = [0.0, {i}0.0, -5.0]\n")).collect();
    let text = format!("gravity_m_s2 = [9.80665, 0.0, 0.0]\n{PUMA}{links}");
    let model = RobotModel::from_toml_str(&text).unwrap();
    assert_eq!(model.masses.len(), 6);
    assert_eq!(model.masses[2].mass, 3.5);
    assert_eq!(model.masses[2].com, nalgebra::Vector3::new(0.0, 30.0, -5.0));
    assert_eq!(model.gravity, nalgebra::Vector3::new(9.80665, 0.0, 0.0));
    assert_eq!(RobotModel::from_toml_str(&model.to_toml_string()).unwrap(), model);
    assert!(!puma.to_toml_string().contains("links") && !puma.to_toml_string().contains("gravity"));

    let five: String = links.splitn(7, "\n[[links]]").take(6).collect::<Vec<_>>().join("\n[[links]]");
    assert_eq!(
        error_of(&format!("{PUMA}{five}")),
        "field `links`: one [[links]] table per joint (6), found 5"
    );
    let negative = links.replacen("mass_kg = 1.5", "mass_kg = -1.5", 1);
    assert_eq!(
        error_of(&format!("{PUMA}{negative}")),
        "field `links[0].mass_kg`: a number from 0 to 100000 kg, found -1.5"
    );
}

/// A joint's compliance and play read in its kind's unit and write back exactly; the other
/// kind's field is refused, naming the joint.
#[test]
fn joint_compliances_and_plays_read_in_their_unit() {
    let text = PUMA.replacen(
        "limits_deg = [-45.0, 225.0]",
        "limits_deg = [-45.0, 225.0]\ncompliance_rad_per_nm = 4e-5\nplay_deg = 0.02",
        1,
    );
    assert_ne!(text, PUMA, "the test must change the file");
    let model = RobotModel::from_toml_str(&text).unwrap();
    assert_eq!(model.joints[1].compliance, 4e-5);
    assert!((model.joints[1].play - 0.02f64.to_radians()).abs() < 1e-15);
    let again = RobotModel::from_toml_str(&model.to_toml_string()).unwrap();
    assert_eq!(again.joints[1].compliance, model.joints[1].compliance);
    assert!((again.joints[1].play - model.joints[1].play).abs() < 1e-15);
    let wrong = text.replace("compliance_rad_per_nm", "compliance_mm_per_n");
    assert_eq!(
        error_of(&wrong),
        "field `joints[1].compliance_mm_per_n`: a revolute joint's compliance as compliance_rad_per_nm"
    );
    assert_eq!(
        error_of(&text.replace("play_deg", "play_mm")),
        "field `joints[1].play_mm`: a revolute joint's play as play_deg"
    );
}
