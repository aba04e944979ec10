//! One test per rule between flags (and per flag checked on its own): the command line parsed
//! by clap as the binary parses it, the request built, the message or the request checked.

use super::*;
use crate::cli::args::JointValues;
use crate::cli::{Cli, Command};
use clap::Parser;
use robocal::calibration::DataKind;

/// The command after `robocal`, parsed by clap; its error as text.
fn parse(args: &[&str]) -> Result<Command, String> {
    Cli::try_parse_from(["robocal"].iter().chain(args)).map(|cli| cli.command).map_err(|e| e.to_string())
}

/// `base` and `args` parsed by clap, and the request `build` makes of the command: the
/// request, or the message of clap or of the rule broken.
fn request<R>(
    base: &[&str],
    args: &[&str],
    build: impl FnOnce(Command) -> Result<R, UsageError>,
) -> Result<R, String> {
    build(parse(&[base, args].concat())?).map_err(|e| e.0)
}

/// `robocal calibrate --model puma560 --data d.csv` with `args`, `d.csv` a marker file.
fn calibrate(args: &[&str]) -> Result<CalibrateObservationsRequest, String> {
    calibrate_model("puma560", args)
}

/// `robocal calibrate --model MODEL --data d.csv` with `args`, `d.csv` a marker file.
fn calibrate_model(model: &str, args: &[&str]) -> Result<CalibrateObservationsRequest, String> {
    request(&["calibrate", "--model", model, "--data", "d.csv"], args, |command| match command {
        Command::Calibrate(args) => match CalibrationRequest::from_args(*args, &[DataKind::Markers])? {
            CalibrationRequest::Observations(request) => Ok(*request),
            other => panic!("routed as {other:?}"),
        },
        other => panic!("parsed as {other:?}"),
    })
}

/// `robocal plan --model puma560 --points 12` with `args`.
fn plan(args: &[&str]) -> Result<PlanRequest, String> {
    request(&["plan", "--model", "puma560", "--points", "12"], args, |command| match command {
        Command::Plan(args) => PlanRequest::from_args(*args),
        other => panic!("parsed as {other:?}"),
    })
}

/// `robocal observability poses.csv --model puma560` with `args`.
fn observability(args: &[&str]) -> Result<ObservabilityRequest, String> {
    request(&["observability", "poses.csv", "--model", "puma560"], args, |command| match command {
        Command::Observability(args) => ObservabilityRequest::from_args(*args),
        other => panic!("parsed as {other:?}"),
    })
}

/// `robocal repeatability --model puma560 --data r.csv` with `args`.
fn repeatability(args: &[&str]) -> Result<RepeatabilityRequest, String> {
    request(&["repeatability", "--model", "puma560", "--data", "r.csv"], args, |command| match command {
        Command::Repeatability(args) => RepeatabilityRequest::from_args(*args),
        other => panic!("parsed as {other:?}"),
    })
}

/// The message of a refused command line.
fn refused<T: std::fmt::Debug>(result: Result<T, String>) -> String {
    result.expect_err("refused")
}

const SIGMAS: &str = "0.007,0.007,0.007,0.002,0.002,0.002";

#[test]
fn the_default_calibration_fits_the_joints_base_and_markers_by_the_default_estimator() {
    let request = calibrate(&[]).unwrap();
    assert_eq!(request.model, ModelRef::named("puma560"));
    // wls unless asked: ols where the data and flags give no noise at all (cli::observations).
    assert_eq!((request.method, request.estimator_given), (Method::Given(Estimator::Wls), false));
    assert_eq!(request.joints, JointParams::All);
    assert!(request.estimate_base && request.estimate_markers);
    assert_eq!((request.noise, request.units, request.iterations, request.folds), (None, None, 200, None));
}

#[test]
fn joint_unit_and_length_unit_go_together() {
    let message = refused(calibrate(&["--joint-unit", "deg"]));
    assert_eq!(message, "--joint-unit and --length-unit go together");
    assert_eq!(refused(repeatability(&["--length-unit", "m"])), message);
    let units = Some(Units { joints_in_degrees: false, lengths_in_metres: true });
    assert_eq!(calibrate(&["--joint-unit", "rad", "--length-unit", "m"]).unwrap().units, units);
    assert_eq!(repeatability(&["--joint-unit", "rad", "--length-unit", "m"]).unwrap().units, units);
    assert!(
        refused(calibrate(&["--joint-unit", "grad", "--length-unit", "m"]))
            .contains("[possible values: deg, rad]")
    );
}

#[test]
fn a_noise_file_gives_every_sigma_so_takes_no_sigma_flag() {
    for flags in [["--joint-sigma-deg", SIGMAS], ["--sigma-mm", "0.5"], ["--sigma-orientation-deg", "0.1"]] {
        let message = refused(calibrate(&[&["--noise", "n.toml"], &flags[..]].concat()));
        assert!(message.starts_with("--noise gives the joint noise and the measurement sigmas"), "{message}");
    }
    let request = calibrate(&["--noise", "n.toml"]).unwrap();
    assert_eq!(request.noise, Some("n.toml".into()));
    assert_eq!(request.method, Method::Given(Estimator::Wls), "wls when the noise is given");
}

#[test]
fn measurement_sigmas_are_the_sigmas_of_rows_that_give_none_with_or_without_joint_sigmas() {
    let request = calibrate(&["--sigma-mm", "0.5"]).unwrap();
    assert_eq!((request.sigmas.length_mm, request.joint_sigma_deg), (Some(0.5), None));
    let request = calibrate(&["--joint-sigma-deg", SIGMAS, "--sigma-mm", "0.5"]).unwrap();
    assert_eq!(request.sigmas.length_mm, Some(0.5));
    assert_eq!(request.joint_sigma_deg, Some(vec![0.007, 0.007, 0.007, 0.002, 0.002, 0.002]));
    // Zero is none, as the flags' default.
    assert_eq!(calibrate(&["--sigma-mm", "0"]).unwrap().sigmas.length_mm, None);
}

#[test]
fn fgls_estimates_the_noise_so_none_is_given() {
    let message = refused(calibrate(&["--estimator", "fgls", "--joint-sigma-deg", SIGMAS]));
    assert_eq!(message, "--estimator fgls estimates the noise: do not give --noise or --joint-sigma-deg");
    assert!(
        refused(calibrate(&["--estimator", "fgls", "--noise", "n.toml"])).starts_with("--estimator fgls")
    );
    assert_eq!(calibrate(&["--estimator", "fgls"]).unwrap().method, Method::Feasible);
}

#[test]
fn every_estimator_is_taken_and_said_to_be_given() {
    // Whether the data give a noise is known only once they are read: a weighted estimator
    // without one is refused then (kinds_markers::a_weighted_estimator_needs_a_noise...).
    for (name, estimator) in [
        ("ols", Estimator::Ols),
        ("wls", Estimator::Wls),
        ("wls-diag", Estimator::WlsDiag),
        ("wls-sigma", Estimator::WlsSigma),
    ] {
        let request = calibrate(&["--estimator", name]).unwrap();
        assert_eq!((request.method, request.estimator_given), (Method::Given(estimator), true), "{name}");
    }
    assert!(
        refused(calibrate(&["--estimator", "gls"]))
            .contains("[possible values: ols, wls, wls-diag, wls-sigma, fgls]")
    );
}

#[test]
fn folds_are_at_least_2() {
    assert!(
        refused(calibrate(&["--folds", "1"])).contains("for '--folds <FOLDS>': expected a whole number >= 2")
    );
    assert_eq!(calibrate(&["--folds", "2"]).unwrap().folds, Some(2));
}

#[test]
fn folds_do_not_go_with_fgls() {
    let message = refused(calibrate(&["--estimator", "fgls", "--folds", "5"]));
    assert_eq!(
        message,
        "--folds with --estimator fgls: not supported; estimate the noise once and give --noise"
    );
}

#[test]
fn out_urdf_needs_a_urdf_model() {
    assert_eq!(refused(calibrate(&["--out-urdf", "c.urdf"])), "--out-urdf needs a URDF model");
}

#[test]
fn links_choose_a_chain_of_a_urdf_model_only() {
    let message = refused(calibrate_model("puma560", &["--base-link", "base"]));
    assert_eq!(message, "--base-link and --tip-link choose a chain of a URDF file (`.urdf`)");
    let request = calibrate_model("arm.urdf", &["--tip-link", "flange"]).unwrap();
    let chain =
        ModelRef { name: "arm.urdf".into(), base_link: None, tip_link: Some("flange".into()), payload: None };
    assert_eq!(request.model, chain, "the base link defaults to the root, found when the file is read");
    let full = ["--base-link", "base", "--tip-link", "flange", "--out-urdf", "c.urdf"];
    let request = calibrate_model("arm.urdf", &full).unwrap();
    let chain = ModelRef { base_link: Some("base".into()), ..chain };
    assert_eq!((request.model, request.out_urdf), (chain, Some("c.urdf".into())));
}

#[test]
fn iterations_are_at_least_1() {
    assert!(
        refused(calibrate(&["--iterations", "0"]))
            .contains("for '--iterations <ITERATIONS>': expected a whole number >= 1")
    );
    assert_eq!(calibrate(&["--iterations", "1"]).unwrap().iterations, 1);
}

#[test]
fn sigmas_are_finite_not_negative_and_plausible() {
    for (flag, bound) in [
        ("--joint-sigma-deg=0.1,-0.1,0,0,0,0", "1e3"),
        ("--joint-sigma-deg=0.1,1e4,0,0,0,0", "1e3"),
        ("--sigma-mm=-1", "1e6"),
        ("--sigma-mm=NaN", "1e6"),
        ("--sigma-mm=2e6", "1e6"),
        ("--sigma-orientation-deg=nan", "1e3"),
        ("--sigma-mm=inf", "1e6"),
    ] {
        let expected = format!("expected a finite number from 0 to {bound}");
        assert!(refused(calibrate(&[flag])).contains(&expected), "{flag}");
        assert!(refused(plan(&[flag])).contains(&expected), "{flag}");
    }
}

#[test]
fn params_all_frees_the_base_and_markers_so_refuses_fixing_them() {
    for fixed in ["--fixed-base", "--fixed-markers"] {
        let message = refused(calibrate(&["--params", "all", fixed]));
        assert_eq!(
            message,
            "--params all frees the base and the markers: with --fixed-base or --fixed-markers, give --params joints"
        );
        let request = calibrate(&["--params", "joints", fixed]).unwrap();
        assert_eq!(request.joints, JointParams::All);
        assert!(!(request.estimate_base && request.estimate_markers));
    }
    let request = calibrate(&["--params", "all"]).unwrap();
    assert_eq!(
        (request.joints, request.estimate_base, request.estimate_markers),
        (JointParams::All, true, true)
    );
}

#[test]
fn params_words_and_names() {
    assert_eq!(calibrate(&["--params", "offsets"]).unwrap().joints, JointParams::Offsets);
    assert_eq!(calibrate(&["--params", "none"]).unwrap().joints, JointParams::None);
    let names = JointParams::Named(vec!["j*.theta".into(), "j2.a".into()]);
    assert_eq!(calibrate(&["--params", "j*.theta, j2.a"]).unwrap().joints, names);
    let message = refused(calibrate(&["--params", "all,j2.a"]));
    assert!(message.contains("`all` is a parameter set: give it alone, not with names"), "{message}");
    assert_eq!(plan(&[]).unwrap().design.params, ParamWords::Joints);
    assert_eq!(plan(&["--params", "all"]).unwrap().design.params, ParamWords::All);
}

#[test]
fn params_none_is_for_calibrate_only() {
    let message = "--params none: nothing to assess; give joints, all, offsets, or parameter names";
    assert_eq!(refused(plan(&["--params", "none"])), message);
    assert_eq!(refused(observability(&["--params", "none"])), message);
}

#[test]
fn markers_are_three_finite_numbers() {
    let request = calibrate(&["--marker", "50,0,150", "--marker=-40,60,120"]).unwrap();
    assert_eq!(request.markers, [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)]);
    for bad in ["50,0", "50,0,1,2", "50,x,1", "50,0,inf", "50,0,1e300"] {
        let message = refused(calibrate(&["--marker", bad]));
        assert!(message.contains("expected three finite numbers x,y,z in mm"), "{bad}: {message}");
    }
    assert_eq!(repeatability(&["--marker", "1,2,3"]).unwrap().markers, [Vector3::new(1.0, 2.0, 3.0)]);
}

#[test]
fn sigma_mm_needs_the_joint_sigmas_in_plan_and_observability() {
    let message = "--sigma-mm needs --joint-sigma-deg too (zeros if the joints are exact)";
    assert_eq!(refused(plan(&["--sigma-mm", "0.01"])), message);
    assert_eq!(refused(observability(&["--sigma-mm", "0.01"])), message);
    let request =
        observability(&["--sigma-mm", "0.01", "--joint-sigma-deg", SIGMAS, "--measured", "pose"]).unwrap();
    assert_eq!(request.design.noise.map(|n| n.sigma_mm), Some(0.01));
    assert_eq!(request.design.measured, Measured::Pose);
}

#[test]
fn the_tool_box_is_six_numbers_each_minimum_at_most_its_maximum() {
    let message = refused(plan(&["--tool-box=-800,-800,0,800,800,-1"]));
    assert!(message.contains("each minimum must not exceed its maximum"), "{message}");
    let message = refused(plan(&["--tool-box", "1,2,3"]));
    assert!(message.contains("expected six finite numbers xmin,ymin,zmin,xmax,ymax,zmax in mm"), "{message}");
    let tool_box = plan(&["--tool-box=-800,-800,0,800,800,1200"]).unwrap().tool_box.unwrap();
    assert_eq!(
        (tool_box.low, tool_box.high),
        (Vector3::new(-800.0, -800.0, 0.0), Vector3::new(800.0, 800.0, 1200.0))
    );
}

#[test]
fn an_excluded_range_is_a_name_and_two_numbers_from_at_most_to() {
    assert!(refused(plan(&["--exclude", "j2:10:-30"])).contains("FROM must not exceed TO"));
    for bad in ["j2:10", "j2:a:10", "j2:0:nan", "j2:0:1:2"] {
        assert!(refused(plan(&["--exclude", bad])).contains("expected JOINT:FROM:TO"), "{bad}");
    }
    let request = plan(&["--exclude", "j2:-30:10", "--exclude", "j3:0:5.5"]).unwrap();
    assert_eq!(request.exclude[0], Excluded { joint: "j2".into(), range: [-30.0, 10.0] });
    assert_eq!(request.exclude[1].to_string(), "j3:0:5.5");
}

#[test]
fn fk_joint_values_are_finite_numbers_separated_by_commas_or_spaces() {
    for text in ["0 45 180", "0, 45,180"] {
        let Command::Fk(args) = parse(&["fk", "--model", "puma560", "--q", text]).unwrap() else {
            panic!("fk")
        };
        assert_eq!(args.q, JointValues(vec![0.0, 45.0, 180.0]));
    }
    let message = parse(&["fk", "--model", "puma560", "--q", "0,inf"]).unwrap_err();
    assert!(message.contains("value 2 is inf, expected a finite number"), "{message}");
    let message = parse(&["fk", "--model", "puma560", "--q", "0,1e308,0,0,0,0"]).unwrap_err();
    assert!(
        message.contains("value 2 is 1e308, expected a finite number of magnitude at most 1e6"),
        "{message}"
    );
}

#[test]
fn plan_sizes_and_iterations_are_bounded() {
    assert_eq!(refused(plan(&["--candidates", "1000001"])), "--candidates 1000001: at most 1000000");
    let message =
        refused(request(&["plan", "--model", "puma560", "--points", "99999999999"], &[], |c| match c {
            Command::Plan(args) => PlanRequest::from_args(*args),
            other => panic!("parsed as {other:?}"),
        }));
    assert_eq!(message, "--points 99999999999: at most 1000000");
    let message = refused(calibrate(&["--iterations", "1001"]));
    assert!(message.contains("expected a whole number from 1 to 1000"), "{message}");
}

/// `robocal evaluate --model m.toml --data a.csv` with `args`.
fn evaluate(args: &[&str]) -> Result<EvaluateRequest, String> {
    request(&["evaluate", "--model", "m.toml", "--data", "a.csv"], args, |command| match command {
        Command::Evaluate(args) => EvaluateRequest::from_args(*args),
        other => panic!("parsed as {other:?}"),
    })
}

#[test]
fn evaluate_takes_several_files_and_a_urdf_with_the_written_links() {
    let files = evaluate(&["b.csv", "--data", "c.csv", "--markers", "1,3"]).unwrap();
    assert_eq!(files.data, ["a.csv", "b.csv", "c.csv"].map(PathBuf::from));
    assert_eq!(files.marker_ids, Some(vec![1, 3]));
    let urdf = request(&["evaluate", "--model", "c.urdf", "--data", "a.csv"], &[], |command| match command {
        Command::Evaluate(args) => EvaluateRequest::from_args(*args),
        other => panic!("parsed as {other:?}"),
    })
    .unwrap();
    let (base_link, tip_link) = (urdf.model.base_link.unwrap(), urdf.model.tip_link.unwrap());
    assert_eq!((base_link.as_str(), tip_link.as_str()), ("measuring_frame", "tool"));
}

#[test]
fn evaluate_wants_the_joint_noise_with_sigma_mm_and_markers_from_1() {
    let message = evaluate(&["--sigma-mm", "0.01"]).unwrap_err();
    assert!(message.contains("--sigma-mm needs --joint-sigma-deg"), "{message}");
    let message = evaluate(&["--markers", "0"]).unwrap_err();
    assert!(message.contains("expected a whole number >= 1"), "{message}");
    assert!(evaluate(&["--noise", "n.toml", "--joint-sigma-deg", "0,0,0,0,0,0"]).is_err());
}

#[test]
fn calibrate_takes_the_markers_to_fit_and_the_report_files() {
    let request =
        calibrate(&["--markers", "2,3", "--poses-csv", "p.csv", "--figures", "f", "--html", "r.html"])
            .unwrap();
    assert_eq!(request.marker_ids, Some(vec![2, 3]));
    assert_eq!(request.report.poses_csv, Some(PathBuf::from("p.csv")));
    assert_eq!(request.report.figures, Some(PathBuf::from("f")));
    assert_eq!(request.report.html, Some(PathBuf::from("r.html")));
}

#[test]
fn a_payload_is_a_mass_at_a_point_of_the_tip_frame() {
    let loaded = evaluate(&["--payload-kg", "2", "--payload-com-mm", "0,-10,50"]).unwrap();
    let payload = loaded.model.payload.unwrap();
    assert_eq!((payload.mass, payload.com), (2.0, nalgebra::Vector3::new(0.0, -10.0, 50.0)));
    assert_eq!(
        evaluate(&["--payload-kg", "1.5"]).unwrap().model.payload.unwrap().com,
        nalgebra::Vector3::zeros()
    );
    assert!(
        evaluate(&["--payload-kg", "-1"])
            .unwrap_err()
            .contains("--payload-kg: a number from 0 to 100000 kg, found -1")
    );
    assert!(
        evaluate(&["--payload-kg", "1", "--payload-com-mm", "1,2"]).unwrap_err().contains("three finite")
    );
    assert!(evaluate(&["--payload-com-mm", "1,2,3"]).is_err());
    assert_eq!(calibrate(&["--payload-kg", "3"]).unwrap().model.payload.map(|p| p.mass), Some(3.0));
}

/// `--prior` takes entries and presets, repeated, in order; a bad entry names itself and what
/// was expected. `--loss` takes squared, huber[:K], cauchy[:K].
#[test]
fn priors_and_losses_are_read_in_order() {
    let r = calibrate(&["--prior", "machined,j2.a=1mm", "--prior", "j3.alpha=0.1deg", "--loss", "huber:2"])
        .unwrap();
    let targets: Vec<&str> = r.prior.iter().map(|e| e.target.as_str()).collect();
    assert_eq!(targets, ["lengths", "angles", "offsets", "offsets", "plays", "plays", "j2.a", "j3.alpha"]);
    assert_eq!(r.loss, robocal::calibration::Loss::Huber(2.0));
    assert_eq!(calibrate(&[]).unwrap().loss, robocal::calibration::Loss::Squared);
    let bad = calibrate(&["--prior", "j2.a=1inch"]).unwrap_err();
    assert!(bad.contains("prior `j2.a=1inch`: unknown unit `inch`"), "{bad}");
    let bad = calibrate(&["--loss", "l1"]).unwrap_err();
    assert!(bad.contains("unknown loss `l1`"), "{bad}");
}

#[test]
fn select_takes_its_criterion_and_cv_the_folds() {
    let request = calibrate(&["--select", "cv"]).unwrap();
    assert_eq!((request.select, request.folds), (Some(Criterion::Cv { folds: DEFAULT_FOLDS }), None));
    let request = calibrate(&["--select", "cv", "--folds", "3"]).unwrap();
    assert_eq!(
        (request.select, request.folds),
        (Some(Criterion::Cv { folds: 3 }), Some(3)),
        "the selection's folds and the nested cross-validation's"
    );
    let request = calibrate(&["--select", "bic", "--folds", "3"]).unwrap();
    assert_eq!((request.select, request.folds), (Some(Criterion::Bic), Some(3)), "the cross-validation's");
    assert_eq!(calibrate(&["--select", "t"]).unwrap().select, Some(Criterion::T));
    assert_eq!(calibrate(&[]).unwrap().select, None);
    assert!(refused(calibrate(&["--select", "aic"])).contains("[possible values: cv, bic, t]"));
    assert_eq!(
        refused(calibrate(&["--select", "t", "--estimator", "fgls"])),
        "--select with --estimator fgls: not supported; estimate the noise once and give --noise"
    );
}

#[test]
fn hold_and_keep_take_names_and_patterns() {
    let request = calibrate(&["--hold", "j*.beta,j2.d", "--keep", "j1.theta"]).unwrap();
    assert_eq!(
        (request.gauge.hold, request.gauge.keep),
        (vec!["j*.beta".to_string(), "j2.d".into()], vec!["j1.theta".to_string()])
    );
    let request = calibrate(&[]).unwrap();
    assert!(request.gauge.hold.is_empty() && request.gauge.keep.is_empty());
    assert_eq!(
        refused(calibrate(&["--hold", "j1.theta", "--keep", "j1.theta"])),
        "`j1.theta` is given to both --hold and --keep: choose one"
    );
    assert!(refused(calibrate(&["--select", "cv", "--params", "none"])).contains("not with --params none"));
}

#[test]
fn fgls_takes_no_priors_and_no_robust_loss() {
    let fgls = ["--estimator", "fgls"];
    let message = refused(calibrate(&[&fgls[..], &["--prior", "machined"]].concat()));
    assert!(message.starts_with("--prior with --estimator fgls: not supported"), "{message}");
    let message = refused(calibrate(&[&fgls[..], &["--loss", "huber"]].concat()));
    assert!(message.starts_with("--loss with --estimator fgls: not supported"), "{message}");
    assert!(calibrate(&fgls).is_ok());
}

/// `robocal calibrate-observations --model puma560 --data d.csv` with `args`.
fn observations(args: &[&str]) -> Result<CalibrateObservationsRequest, String> {
    request(&["calibrate-observations", "--model", "puma560", "--data", "d.csv"], args, |command| {
        match command {
            Command::CalibrateObservations(args) => CalibrateObservationsRequest::from_args(*args),
            other => panic!("parsed as {other:?}"),
        }
    })
}

/// `--estimator fgls` on observation files refuses what it refuses on a marker file, in the
/// same words: a given joint noise, `--folds`, `--select`, a prior, a robust loss.
#[test]
fn fgls_on_observation_files_refuses_what_it_refuses_on_markers() {
    let fgls = ["--estimator", "fgls"];
    let with = |more: &[&str]| observations(&[&fgls[..], more].concat()).unwrap_err();
    assert_eq!(
        with(&["--joint-sigma-deg", SIGMAS]),
        "--estimator fgls estimates the noise: do not give --noise or --joint-sigma-deg"
    );
    assert_eq!(
        with(&["--folds", "5"]),
        "--folds with --estimator fgls: not supported; estimate the noise once and give --noise"
    );
    assert_eq!(
        with(&["--select", "bic"]),
        "--select with --estimator fgls: not supported; estimate the noise once and give --noise"
    );
    assert!(with(&["--prior", "machined"]).starts_with("--prior with --estimator fgls: not supported"));
    assert!(with(&["--prior", "auto"]).starts_with("--prior with --estimator fgls: not supported"));
    assert!(with(&["--loss", "huber"]).starts_with("--loss with --estimator fgls: not supported"));
}

#[test]
fn calibrate_observations_weights_by_default_and_takes_every_estimator() {
    let request = observations(&["--data", "e.csv", "--tool", "1,2,3", "--fixed-tool"]).unwrap();
    assert_eq!(request.method, Method::Given(Estimator::Wls));
    assert_eq!(request.data, [PathBuf::from("d.csv"), PathBuf::from("e.csv")]);
    assert_eq!(request.tool, Some(Vector3::new(1.0, 2.0, 3.0)));
    assert!(!request.estimate_tool);
    assert_eq!(observations(&["--estimator", "ols"]).unwrap().method, Method::Given(Estimator::Ols));
    assert_eq!(observations(&["--estimator", "fgls"]).unwrap().method, Method::Feasible);
    assert_eq!(observations(&["--params", "all"]).unwrap().joints, JointParams::All);
    assert_eq!(
        observations(&["--params", "all", "--fixed-base"]).unwrap_err(),
        "--params all frees the base and the markers: with --fixed-base or --fixed-markers, give --params joints"
    );
    assert_eq!(observations(&["--estimator", "wls-diag"]).unwrap().method, Method::Given(Estimator::WlsDiag));
    assert_eq!(
        observations(&["--estimator", "wls-sigma"]).unwrap().method,
        Method::Given(Estimator::WlsSigma)
    );
    assert!(observations(&["--json", "d.csv"]).unwrap_err().contains("d.csv"));
}

#[test]
fn calibrate_observations_takes_the_markers_in_order() {
    let request = observations(&["--marker", "50,0,150", "--marker=-40,60,120"]).unwrap();
    assert_eq!(request.markers, [Vector3::new(50.0, 0.0, 150.0), Vector3::new(-40.0, 60.0, 120.0)]);
    assert!(observations(&[]).unwrap().markers.is_empty());
    assert!(observations(&["--marker", "1,2"]).is_err());
}

/// `robocal calibrate --model M --data F0.csv ...` with `args`, the files holding `kinds` (M a
/// URDF file with tree views, else puma560).
fn route(kinds: &[DataKind], args: &[&str]) -> Result<CalibrationRequest, String> {
    let data: Vec<String> = (0..kinds.len()).map(|k| format!("f{k}.csv")).collect();
    let model = if kinds.contains(&DataKind::TreeViews) { "torso.urdf" } else { "puma560" };
    let mut head = vec!["calibrate", "--model", model];
    for d in &data {
        head.extend(["--data", d.as_str()]);
    }
    request(&head, args, |command| match command {
        Command::Calibrate(args) => CalibrationRequest::from_args(*args, kinds),
        other => panic!("parsed as {other:?}"),
    })
}

/// A flag that a tree's views give no meaning is refused saying why; one not there yet for
/// trees says so.
#[test]
fn a_tree_refuses_each_flag_saying_why() {
    let tree =
        |flag: &[&str]| route(&[DataKind::TreeViews], &[&["--tips", "a,b"], flag].concat()).unwrap_err();
    let tool = tree(&["--tool", "1,2,3"]);
    assert!(tool.starts_with("--tool and --fixed-tool: views between a tree's branches see"), "{tool}");
    assert!(tree(&["--fixed-base"]).contains("a tree's base is never estimated"));
    assert!(tree(&["--noise", "n.toml"]).contains("their sigma columns and --joint-sigma-deg"));
    // Per session: for a tree too, over two files or more.
    assert!(tree(&["--per-session", "camera*"]).contains("give two --data files or more"));
}

/// A tree's flag with an arm's files is refused for what it is, not for another flag the
/// tree's calibration does not take.
#[test]
fn a_trees_flag_with_an_arms_files_is_refused_for_what_it_is() {
    let out_dir = route(&[DataKind::Markers], &["--out-dir", "d", "--sigma-mm", "0.01"]).unwrap_err();
    assert!(
        out_dir.starts_with("--out-dir: for views between") && out_dir.contains("--out-model"),
        "{out_dir}"
    );
}

/// One command: marker and observation files, one or several, take the one observation
/// calibration, tree views the tree's; a flag the chosen one cannot honour is
/// refused, naming it.
#[test]
fn calibrate_routes_by_the_files_kinds_and_the_flags() {
    use DataKind::{Markers, Observations, TreeViews};
    let is = |r: Result<CalibrationRequest, String>| match r.unwrap() {
        CalibrationRequest::Observations(_) => "observations",
        CalibrationRequest::Tree(_) => "tree",
    };
    assert_eq!(is(route(&[Markers], &["--select", "cv"])), "observations");
    assert_eq!(is(route(&[Observations], &[])), "observations");
    assert_eq!(is(route(&[Markers, Markers], &[])), "observations");
    assert_eq!(is(route(&[Markers, Observations], &["--prior", "machined"])), "observations");
    assert_eq!(is(route(&[Markers], &["--tool", "1,2,3"])), "observations");
    assert_eq!(is(route(&[TreeViews], &["--tips", "a,b"])), "tree");
    let refused = |kinds: &[DataKind], args: &[&str]| route(kinds, args).unwrap_err();
    match route(&[Observations], &["--select", "cv", "--folds", "4"]).unwrap() {
        CalibrationRequest::Observations(r) => assert_eq!(r.select, Some(Criterion::Cv { folds: 4 })),
        other => panic!("{other:?}"),
    }
    assert!(
        refused(&[Observations], &["--select", "t", "--params", "none"]).contains("not with --params none")
    );
    match route(&[Observations], &["--html", "r.html", "--poses-csv", "p.csv", "--figures", "f"]).unwrap() {
        CalibrationRequest::Observations(r) => {
            assert_eq!(r.report.html, Some("r.html".into()));
            assert_eq!((r.report.poses_csv, r.report.figures), (Some("p.csv".into()), Some("f".into())));
        }
        other => panic!("{other:?}"),
    }
    match route(&[TreeViews], &["--tips", "a,b", "--poses-csv", "-", "--figures", "f"]).unwrap() {
        CalibrationRequest::Tree(r) => {
            assert_eq!((r.report.poses_csv, r.report.figures), (Some("-".into()), Some("f".into())));
        }
        other => panic!("{other:?}"),
    }
    assert!(
        refused(&[TreeViews], &["--tips", "a,b", "--poses-csv", "f0.csv"]).contains("f0.csv"),
        "an input overwritten"
    );
    assert!(refused(&[Observations], &["--html", "r.html", "--json", "r.html"]).contains("r.html"));
    match route(
        &[Markers, Observations],
        &["--fixed-base", "--fixed-markers", "--markers", "2", "--sigma-mm", "0.05"],
    )
    .unwrap()
    {
        CalibrationRequest::Observations(r) => {
            assert!(!r.estimate_base && !r.estimate_markers, "{r:?}");
            assert_eq!(r.marker_ids, Some(vec![2]));
            assert_eq!((r.sigmas.length_mm, r.sigmas.angle_rad), (Some(0.05), None));
        }
        other => panic!("{other:?}"),
    }
    match route(&[Observations], &["--noise", "n.toml"]).unwrap() {
        CalibrationRequest::Observations(r) => assert_eq!(r.noise, Some("n.toml".into())),
        other => panic!("{other:?}"),
    }
    assert!(
        refused(&[Observations], &["--noise", "n.toml", "--joint-sigma-deg", "0.01"])
            .starts_with("--noise gives the joint noise")
    );
    assert!(refused(&[TreeViews, Observations], &[]).contains("fitted on their own"));
    assert!(refused(&[Observations], &["--tips", "a"]).starts_with("--tips: for views between"));
    assert_eq!(
        is(route(&[TreeViews], &["--prior", "machined", "--loss", "huber", "--hold", "torso.z"])),
        "tree"
    );
    match route(&[TreeViews], &["--select", "bic"]).unwrap() {
        CalibrationRequest::Tree(r) => assert_eq!(r.select, Some(Criterion::Bic)),
        other => panic!("{other:?}"),
    }
    assert!(refused(&[TreeViews], &["--out-model", "m.toml"]).contains("--out-dir"));
    match route(&[TreeViews], &["--out-urdf", "calibrated.urdf"]).unwrap() {
        CalibrationRequest::Tree(r) => assert_eq!(r.out_urdf, Some("calibrated.urdf".into())),
        other => panic!("{other:?}"),
    }
}

/// `robocal calibrate-tree --model MODEL --data v.csv` with `args`.
fn calibrate_tree(model: &str, args: &[&str]) -> Result<CalibrateTreeRequest, String> {
    request(&["calibrate-tree", "--model", model, "--data", "v.csv"], args, |command| match command {
        Command::CalibrateTree(args) => CalibrateTreeRequest::from_args(*args),
        other => panic!("parsed as {other:?}"),
    })
}

#[test]
fn a_tree_is_a_urdf_calibrated_by_ols_or_wls_of_its_joints() {
    let r = calibrate_tree("torso.urdf", &["--tips", "head_camera,l_hand"]).unwrap();
    assert_eq!(r.estimator, Estimator::Wls);
    assert_eq!(r.joints, JointParams::All);
    assert_eq!(r.tips, ["head_camera", "l_hand"]);
    assert!(refused(calibrate_tree("puma560", &[])).contains("--model: a URDF file"));
    let fgls = calibrate_tree("torso.urdf", &["--estimator", "fgls"]).unwrap();
    assert!(fgls.feasible && fgls.estimator == Estimator::Ols);
    assert!(!r.feasible);
    assert!(
        refused(calibrate_tree("torso.urdf", &["--estimator", "fgls", "--loss", "huber"]))
            .starts_with("--loss with --estimator fgls: not supported")
    );
    assert!(
        refused(calibrate_tree("torso.urdf", &["--estimator", "fgls", "--joint-sigma-deg", "0.01"]))
            .starts_with("--estimator fgls estimates the noise")
    );
    assert!(refused(calibrate_tree("torso.urdf", &["--estimator", "wls-diag"])).contains("ols, wls or fgls"));
    assert!(refused(calibrate_tree("torso.urdf", &["--params", "all"])).contains("never estimated"));
    assert!(refused(calibrate_tree("torso.urdf", &["--json", "v.csv"])).contains("--json"));
}

/// `--prior auto` takes `fabricated`, `auto:PRESET` that preset, once, beside other entries;
/// an unknown preset, a second auto, fgls and calibrate-observations are refused.
#[test]
fn prior_auto_takes_a_preset_to_scale() {
    let request = calibrate(&["--prior", "auto", "--prior", "j2.a=1mm"]).unwrap();
    assert_eq!(request.auto_prior.as_ref().map(|a| a.preset.as_str()), Some("fabricated"));
    assert_eq!(request.prior.len(), 1);
    let request = calibrate(&["--prior", "auto:machined"]).unwrap();
    let auto = request.auto_prior.unwrap();
    assert_eq!((auto.preset.as_str(), auto.entries.len()), ("machined", 6));
    assert!(request.prior.is_empty());
    assert!(
        refused(calibrate(&["--prior", "auto:milled"]))
            .contains("a preset among machined, precision, fabricated")
    );
    assert!(
        refused(calibrate(&["--prior", "auto", "--prior", "auto:machined"]))
            .contains("--prior auto: give it once")
    );
    assert!(
        refused(calibrate(&["--prior", "auto", "--estimator", "fgls"]))
            .contains("--prior with --estimator fgls")
    );
    let request = observations(&["--prior", "auto:precision", "--prior", "j1.theta=0.1deg"]).unwrap();
    assert_eq!(request.auto_prior.map(|a| a.preset), Some("precision".to_string()));
    assert_eq!(request.prior.len(), 1, "the explicit entry, on top of the scaled preset");
}
