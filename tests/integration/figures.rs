//! The figures of a calibration as the command writes them: signed components against each
//! joint, and against each joint's gravity load when the model has masses.

use assert_cmd::Command;

/// The names of the figures `calibrate --model MODEL` writes for the README's data, and the
/// folder (to be removed by the caller).
fn figures_of(model: &str) -> (Vec<String>, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("robocal-figures-{}-{model}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let output = Command::cargo_bin("robocal")
        .unwrap()
        .args(["-q", "calibrate", "--model", model, "--data", "examples/puma560-measurements.csv"])
        .args([
            "--validate",
            "examples/puma560-validation.csv",
            "--marker",
            "50,0,150",
            "--marker=-40,60,120",
        ])
        .arg("--figures")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    (names, dir)
}

#[test]
fn a_model_with_masses_adds_the_errors_against_each_loaded_joints_gravity_load() {
    let (names, dir) = figures_of("puma560-masses");
    let torques: Vec<&str> = names.iter().map(String::as_str).filter(|n| n.contains("torque")).collect();
    // j1's axis is vertical: gravity puts no load on it, so it has no figure.
    assert_eq!(
        torques,
        [
            "error-vs-torque-j2.svg",
            "error-vs-torque-j3.svg",
            "error-vs-torque-j4.svg",
            "error-vs-torque-j5.svg"
        ]
    );
    let svg = std::fs::read_to_string(dir.join("error-vs-torque-j2.svg")).unwrap();
    assert!(svg.contains("gravity load on j2 (N·m)"), "the load's unit on the axis");
    let against_joint = std::fs::read_to_string(dir.join("error-vs-j2.svg")).unwrap();
    for panel in ["x (mm)", "y (mm)", "z (mm)"] {
        assert!(against_joint.contains(panel), "the signed component {panel}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
    let (names, dir) = figures_of("puma560");
    assert!(names.iter().all(|n| !n.contains("torque")), "no masses, no load figures: {names:?}");
    assert!(names.contains(&"error-vs-j6.svg".to_string()), "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
