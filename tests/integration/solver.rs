//! The solver converges (#24 item 6): every example data set of the project, through the
//! command line as a user runs it, with the squared loss and robust ones, converges within the
//! default step limit, the steps of a robust fit's re-weightings counted together. The trust
//! region's agreement with Gauss-Newton and the draw-wire case are in `estimation.rs` and
//! `kinds.rs` (`the_trust_region_is_gauss_newton_where_gauss_newton_converges`,
//! `a_draw_wire_converges_from_three_starts_to_one_estimate`).

use robocal::estimation::RefineOptions;

/// `robocal calibrate -q ARGS --json -`'s report.
fn report(args: &[&str]) -> serde_json::Value {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_robocal"))
        .args(["calibrate", "-q"])
        .args(args)
        .args(["--json", "-"])
        .output()
        .unwrap();
    assert!(output.status.success(), "{args:?}: {}", String::from_utf8_lossy(&output.stderr));
    serde_json::from_slice(&output.stdout).unwrap()
}

/// Every example (the PUMA's markers, ball bar, camera and markers with the ball bar; the
/// torso's views; the arm7 benchmark with every joint parameter, its compliances and plays, with
/// and without priors) converges under the squared loss, Huber's and Cauchy's, within the
/// default limit (200 steps in all), no `not_converged` warning; the robust fits in at most 3
/// times the plain fit's steps plus 20.
#[test]
fn every_example_converges_within_the_default_limit() {
    let joint = "--joint-sigma-deg=0.007,0.007,0.007,0.002,0.002,0.002";
    let puma = ["--model", "puma560", "--marker", "50,0,150", "--marker=-40,60,120", "--tool", "50,0,150"];
    let tool = ["--model", "puma560", "--tool", "50,0,150"];
    let arm7: Vec<&'static str> =
        super::nested::ARM7.iter().chain(&["--params", "joint*.*"]).copied().collect();
    let with = |base: &[&'static str], more: &[&'static str]| -> Vec<&'static str> {
        base.iter().chain(more).copied().collect()
    };
    let cases: Vec<Vec<&str>> = vec![
        with(&puma[..5], &["--data", "examples/puma560-measurements.csv", joint, "--sigma-mm", "0.01"]),
        with(&tool, &["--data", "examples/puma560-ballbar.csv", joint]),
        with(&["--model", "puma560"], &["--data", "examples/puma560-camera.csv", joint]),
        with(
            &puma,
            &["--data", "examples/puma560-measurements.csv", "--data", "examples/puma560-ballbar.csv", joint],
        ),
        vec!["--model", "presets/torso.urdf", "--data", "examples/torso/views.csv"],
        arm7.to_vec(),
        with(&arm7, &["--prior", "fabricated"]),
    ];
    let limit = RefineOptions::default().max_iterations as u64;
    for case in &cases {
        let mut plain = 0;
        for loss in [None, Some("huber"), Some("cauchy")] {
            let mut args = case.clone();
            args.extend(loss.map(|l| ["--loss", l]).into_iter().flatten());
            let r = report(&args);
            let steps = r["iterations"].as_u64().unwrap_or_else(|| panic!("{args:?}: {r}"));
            assert_eq!(r["converged"], true, "{args:?}: {steps} steps");
            let causes: Vec<&str> =
                r["warnings"].as_array().unwrap().iter().filter_map(|w| w["cause"].as_str()).collect();
            assert!(!causes.contains(&"not_converged"), "{args:?}: {causes:?}");
            assert!(steps < limit, "{args:?}: {steps} steps");
            match loss {
                None => plain = steps,
                Some(_) => assert!(steps <= 3 * plain + 20, "{args:?}: {steps} steps, the plain fit {plain}"),
            }
        }
    }
}
