//! Mutation fuzzing of every input format, and `calibrate` on random small inputs: whatever
//! the bytes, a reader returns a value or an error that says where (a line, a field, or the
//! parser's own position), and nothing panics.
//!
//! Deterministic (a fixed seed) and short in `cargo test`; for a longer run, set the number
//! of cases per property (README, "Fuzzing"):
//!
//! ```sh
//! ROBOCAL_FUZZ_CASES=50000 cargo test --release --test integration fuzz::
//! ```

use nalgebra::Vector3;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use robocal::calibration::kinds::{KindData, KindOptions, calibrate_kinds, evaluate_kinds};
use robocal::calibration::{JointParams, RepeatabilityData};
use robocal::estimation::{Estimator, NoiseSpec, RefineOptions};
use robocal::model::{ModelError, RobotModel, from_urdf_str};
use robocal::simulation::{Study, StudyError};

const MEASUREMENTS: &str = include_str!("../../examples/puma560-measurements.csv");
const REPEATABILITY: &str = include_str!("../../examples/puma560-repeatability.csv");
const MODEL: &str = include_str!("../../presets/puma560.toml");
const NOISE: &str = include_str!("../../examples/puma560-noise.toml");
const STUDY: &str = include_str!("../../presets/planned-poses.toml");
const DEVICE_STUDY: &str = include_str!("../../presets/device-theodolites.toml");
const BALL_BAR: &str = include_str!("../../examples/puma560-ballbar.csv");
/// Every kind of observation in one file, by a `kind` column.
const OBSERVATIONS: &str = "# units: joints=deg, lengths=mm
kind,j1,j2,j3,j4,j5,j6,j1_b,j2_b,j3_b,j4_b,j5_b,j6_b,distance,point,plane,x,y,z,roll,pitch,yaw,sigma,sigma_angle
pair,0,10,20,0,0,0,5,15,25,0,0,0,123.4,,,,,,,,,0.02,
point,0,10,20,0,0,0,,,,,,,300,2,,,,,,,,,
contact,0,10,20,0,0,0,,,,,,,,,3,,,,,,,,
coordinates,0,10,20,0,0,0,,,,,,,,,,,,812.5,1.5,,,,0.01
";

/// `cases` property cases (or `ROBOCAL_FUZZ_CASES`), from a fixed seed, without regression
/// files.
fn config(cases: u32) -> Config {
    let cases = std::env::var("ROBOCAL_FUZZ_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(cases);
    Config { cases, rng_seed: RngSeed::Fixed(13), failure_persistence: None, ..Config::default() }
}

/// What a mutation inserts: the numbers, separators and markup that broke readers before.
const TOKENS: &[&str] = &[
    "1e308",
    "-1e308",
    "1e300",
    "NaN",
    "inf",
    "-inf",
    "1e-320",
    "99999999999999999999",
    "-0",
    "0",
    "",
    ",",
    ",,",
    "\n",
    "\r",
    "\r\n",
    "\u{feff}",
    "#",
    "# units: joints=rad, lengths=m\n",
    "=",
    "[",
    "]",
    "[]",
    "\"",
    "'",
    "x1",
    "j1",
    "sigma",
    "qw",
    "pose",
    "<",
    ">",
    "/>",
    "<mimic joint=\"j1\"/>",
    "<joint name=\"j1\">",
    "[[joints]]",
    "\u{0}",
    "é",
    "1000000000000",
    "4294967296",
    "-1",
];

/// One edit of a text: at a position (a fraction of its length), one of replace a span by a
/// token, insert a token, delete a span, or duplicate a line.
#[derive(Debug, Clone)]
struct Mutation {
    at: f64,
    kind: u8,
    token: usize,
    span: usize,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    (0.0..1.0f64, 0u8..4, 0..TOKENS.len(), 0usize..12).prop_map(|(at, kind, token, span)| Mutation {
        at,
        kind,
        token,
        span,
    })
}

/// `text` with `mutations` applied in turn.
fn mutate(text: &str, mutations: &[Mutation]) -> String {
    let mut text = text.to_string();
    for m in mutations {
        let boundary = |mut i: usize, text: &str| {
            i = i.min(text.len());
            while !text.is_char_boundary(i) {
                i -= 1;
            }
            i
        };
        let start = boundary((m.at * text.len() as f64) as usize, &text);
        let end = boundary(start + m.span, &text);
        let token = TOKENS[m.token];
        match m.kind {
            0 => text.replace_range(start..end, token),
            1 => text.insert_str(start, token),
            2 => text.replace_range(start..end, ""),
            _ => {
                let line_start = text[..start].rfind('\n').map_or(0, |i| i + 1);
                let line_end = text[start..].find('\n').map_or(text.len(), |i| start + i + 1);
                let line = text[line_start..line_end].to_string();
                text.insert_str(line_start, &line);
            }
        }
    }
    text
}

/// A valid text cut to its first `lines` lines, so that mutations hit its structure often.
fn head(text: &str, lines: usize) -> String {
    text.lines().take(lines).map(|l| format!("{l}\n")).collect()
}

fn puma() -> RobotModel {
    RobotModel::preset("puma560").unwrap()
}

/// A model error says where: the parser's position, or a field.
fn model_error_says_where(error: &ModelError) -> bool {
    match error {
        ModelError::Syntax(e) => e.span().is_some() || !e.message().is_empty(),
        ModelError::Xml(_) => true,
        ModelError::Invalid(field) => !field.field.is_empty() && !field.expected.is_empty(),
        _ => !error.to_string().is_empty(),
    }
}

proptest! {
    #![proptest_config(config(1500))]

    #[test]
    fn measurement_files_read_or_name_the_line(mutations in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(&head(MEASUREMENTS, 8), &mutations);
        if let Err(e) = KindData::from_csv_str(&text, &puma(), None) {
            prop_assert!(e.line >= 1 && e.line <= text.lines().count().max(1) + 1, "{e} in {text:?}");
            let prefix = format!("line {}", e.line);
            prop_assert!(e.to_string().starts_with(&prefix), "{e}");
        }
    }

    #[test]
    fn observation_files_read_or_name_the_line(
        mutations in prop::collection::vec(mutation(), 1..6),
        mixed in any::<bool>(),
    ) {
        let text = mutate(&head(if mixed { OBSERVATIONS } else { BALL_BAR }, 30), &mutations);
        match KindData::from_csv_str(&text, &puma(), None) {
            Ok(data) => {
                prop_assert!(data.check(6).is_ok(), "{text:?}");
                // A fit of what reads: a calibration or an error, never a panic.
                let options = KindOptions {
                    joints: JointParams::Offsets,
                    tool: Vector3::new(50.0, 0.0, 150.0),
                    refine: RefineOptions { max_iterations: 3, ..RefineOptions::default() },
                    ..KindOptions::default()
                };
                let _ = calibrate_kinds(&puma(), &data, &options);
            }
            Err(e) => {
                let prefix = format!("line {}", e.line);
                prop_assert!(e.line >= 1 && e.to_string().starts_with(&prefix), "{e} in {text:?}");
            }
        }
    }

    #[test]
    fn repeatability_files_read_or_name_the_line(mutations in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(&head(REPEATABILITY, 8), &mutations);
        if let Err(e) = RepeatabilityData::from_csv_str(&text, &puma(), None) {
            prop_assert!(e.line >= 1, "{e} in {text:?}");
        }
    }

    #[test]
    fn model_files_read_or_name_the_field(mutations in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(MODEL, &mutations);
        if let Err(e) = RobotModel::from_toml_str(&text) {
            prop_assert!(model_error_says_where(&e), "{e}");
        }
    }

    #[test]
    fn urdf_files_read_or_name_the_field(mutations in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(&crate::urdf::arm_urdf(), &mutations);
        if let Err(e) = from_urdf_str(&text, "base", "flange") {
            prop_assert!(model_error_says_where(&e), "{e}");
        }
    }

    #[test]
    fn noise_files_read_or_name_the_field(mutations in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(NOISE, &mutations);
        if let Err(e) = NoiseSpec::from_toml_str(&text, &puma()) {
            prop_assert!(!robocal::error::chain(&e).is_empty());
        }
    }

    #[test]
    fn study_files_read_or_name_the_field(
        mutations in prop::collection::vec(mutation(), 1..6),
        device in any::<bool>(),
    ) {
        let text = mutate(if device { DEVICE_STUDY } else { STUDY }, &mutations);
        match Study::from_toml_str(&text, |model: &robocal::model::ModelRef| RobotModel::preset(&model.name).ok_or("not a preset")) {
            Ok(study) => {
                // What reads is bounded: its memory is estimated, never overflows.
                prop_assert!(study.memory_estimate(2) > 0);
            }
            Err(StudyError::Invalid(field)) => prop_assert!(!field.field.is_empty(), "{field}"),
            Err(e) => prop_assert!(!robocal::error::chain(&e).is_empty()),
        }
    }
}

/// A joint value (deg): within the PUMA's limits or past them, now and then beyond the bound.
fn joint_value() -> impl Strategy<Value = f64> {
    prop_oneof![30 => -270.0..270.0f64, 1 => Just(0.0), 1 => prop::sample::select(vec![999.0, -1e4, 1e-300])]
}

/// A coordinate of a measurement file (mm): ordinary, large, tiny or extreme.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -2000.0..2000.0f64,
        1 => Just(0.0),
        1 => prop::sample::select(vec![1e-300, -1e-300, 9e5, -1e6, 1e5, 3.0e2]),
    ]
}

proptest! {
    #![proptest_config(config(200))]

    /// `calibrate` on random small measurement files (1-39 poses, 1-2 markers, values anywhere
    /// from the joint limits to the bounds): a calibration or an error, never a panic.
    #[test]
    fn calibrate_on_random_small_inputs_never_panics(
        poses in prop::collection::vec((prop::collection::vec(joint_value(), 6), prop::collection::vec(value(), 6)), 1..40),
        markers in 1usize..3,
        repeat in prop::bool::weighted(0.1),
    ) {
        let mut text = String::from("# units: joints=deg, lengths=mm\nj1,j2,j3,j4,j5,j6");
        for k in 1..=markers {
            text += &format!(",x{k},y{k},z{k}");
        }
        text += "\n";
        for (i, row) in poses.iter().enumerate() {
            let row = if repeat { &poses[0] } else { row };
            let angles = row.0.iter().map(|v| format!("{v}"));
            let coordinates = row.1[..3 * markers].iter().map(|v| format!("{}", v + i as f64));
            text += &angles.chain(coordinates).collect::<Vec<_>>().join(",");
            text += "\n";
        }
        let data = match KindData::from_csv_str(&text, &puma(), None) {
            Ok(data) => data,
            Err(e) => {
                // A row's line (3 on), or the header's (2) for a marker never measured.
                prop_assert!(e.line >= 2 && e.column.is_some(), "{e}");
                return Ok(());
            }
        };
        let options = KindOptions {
            refine: RefineOptions { max_iterations: 5, ..RefineOptions::default() },
            ..crate::marker_options(&puma(), Estimator::Ols, None, &[Vector3::new(50.0, 0.0, 150.0)])
        };
        if let Err(e) = calibrate_kinds(&puma(), &data, &options) {
            prop_assert!(!e.to_string().is_empty());
        }
    }
}

// Issue 25: the commands added since (calibrate-observations above; calibrate-tree, evaluate,
// priors, selection, robust losses, compliance models, study `[truth]` below).

const TORSO_URDF: &str = include_str!("../../presets/torso.urdf");
const TORSO_VIEWS: &str = include_str!("../../examples/torso/views.csv");
const MASSES_MODEL: &str = include_str!("../../presets/puma560-masses.toml");
const COMPLIANCE_STUDY: &str = include_str!("../../presets/compliance.toml");
const PRIORS: &str = "j*.a=0.5mm,j*.alpha=0.05deg,lengths=0.1mm,j2.compliance=1e-4,machined,plays=0.02deg";

fn torso() -> robocal::model::RobotTree {
    let tips = ["head_camera", "l_hand", "r_hand"].map(String::from);
    robocal::model::RobotTree::from_urdf_str(TORSO_URDF, None, &tips).unwrap()
}

/// Calibration options for the fuzzed fits: few steps, the loss and priors given.
fn quick_options(
    model: &RobotModel,
    loss: robocal::calibration::Loss,
    prior: Vec<robocal::estimation::PriorEntry>,
) -> KindOptions {
    KindOptions {
        joints: JointParams::Named(vec!["j*.*".into()]),
        prior,
        loss,
        refine: RefineOptions { max_iterations: 3, ..RefineOptions::default() },
        ..crate::marker_options(model, Estimator::Ols, None, &[Vector3::new(50.0, 0.0, 150.0)])
    }
}

/// A loss of the three, with thresholds ordinary or extreme.
fn loss() -> impl Strategy<Value = robocal::calibration::Loss> {
    use robocal::calibration::Loss;
    let k = prop::sample::select(vec![1.345, 2.385, 1e-300, 1e300, 0.0, -1.0, f64::NAN]);
    prop_oneof![Just(Loss::Squared), k.clone().prop_map(Loss::Huber), k.prop_map(Loss::Cauchy)]
}

proptest! {
    #![proptest_config(config(300))]

    /// `calibrate-tree`: the view file mutated; what reads is fitted (a calibration or an
    /// error) and scored.
    #[test]
    fn tree_view_files_read_or_name_the_line_and_fit_without_a_panic(mutations in prop::collection::vec(mutation(), 1..6)) {
        let tree = torso();
        let text = mutate(&head(TORSO_VIEWS, 14), &mutations);
        match robocal::calibration::tree::TreeData::from_csv_str(&text, &tree, None) {
            Ok(data) => {
                let options = robocal::calibration::kinds::KindOptions {
                    estimator: Estimator::Ols,
                    joint_noise: None,
                    joints: JointParams::Offsets,
                    refine: RefineOptions { max_iterations: 2, ..RefineOptions::default() },
                    ..Default::default()
                };
                if let Ok(c) = robocal::calibration::tree::calibrate_tree(&tree, &data, &options) {
                    let _ = c.score(&data);
                }
            }
            Err(e) => prop_assert!(e.line >= 1 && e.to_string().starts_with(&format!("line {}", e.line)), "{e}"),
        }
    }

    /// `evaluate`: a mutated model with masses scored on a mutated measurement file.
    #[test]
    fn evaluate_scores_what_reads_without_a_panic(
        model_mutations in prop::collection::vec(mutation(), 0..4),
        data_mutations in prop::collection::vec(mutation(), 0..4),
    ) {
        let Ok(model) = RobotModel::from_toml_str(&mutate(MASSES_MODEL, &model_mutations)) else { return Ok(()) };
        let Ok(data) = KindData::from_csv_str(&mutate(&head(MEASUREMENTS, 10), &data_mutations), &model, None) else {
            return Ok(());
        };
        let markers = [(1, Vector3::new(50.0, 0.0, 150.0))];
        if let Ok(options) = KindOptions::as_it_stands(&model, &markers, &data) {
            let _ = evaluate_kinds(&model, &data, &options);
        }
    }

    /// `--prior` and a `[prior]` entry list: parsed or refused naming the entry; what parses
    /// is applied in a fit of the compliant robot with a robust loss.
    #[test]
    fn priors_parse_or_name_the_entry_and_fit_without_a_panic(
        mutations in prop::collection::vec(mutation(), 1..4),
        loss in loss(),
    ) {
        let text = mutate(PRIORS, &mutations);
        match robocal::estimation::PriorEntry::parse_list(&text) {
            Ok(prior) => {
                let model = RobotModel::from_toml_str(MASSES_MODEL).unwrap();
                let data = KindData::from_csv_str(&head(MEASUREMENTS, 14), &model, None).unwrap();
                let _ = calibrate_kinds(&model, &data, &quick_options(&model, loss, prior));
            }
            Err(e) => prop_assert!(e.to_string().starts_with("prior `"), "{e}"),
        }
    }

    /// A compliance model (masses, compliances, plays, a payload) mutated: read or named, and
    /// what reads calibrates its compliances (or says why not) on the example's poses.
    #[test]
    fn compliance_models_read_or_name_the_field_and_calibrate_without_a_panic(
        mutations in prop::collection::vec(mutation(), 1..6),
        loss in loss(),
    ) {
        let text = mutate(MASSES_MODEL, &mutations);
        match RobotModel::from_toml_str(&text) {
            Ok(model) => {
                let Ok(data) = KindData::from_csv_str(&head(MEASUREMENTS, 14), &model, None) else { return Ok(()) };
                let _ = calibrate_kinds(&model, &data, &quick_options(&model, loss, Vec::new()));
            }
            Err(e) => prop_assert!(model_error_says_where(&e), "{e}"),
        }
    }

    /// A study with `[truth]` (compliances, plays, a payload) mutated: read or named.
    #[test]
    fn truth_studies_read_or_name_the_field(mutations in prop::collection::vec(mutation(), 1..6)) {
        let text = mutate(COMPLIANCE_STUDY, &mutations);
        let robot = |model: &robocal::model::ModelRef| robocal::io::load_model(model).map_err(|e| e.to_string());
        match Study::from_toml_str(&text, robot) {
            Ok(study) => prop_assert!(study.memory_estimate(2) > 0),
            Err(StudyError::Invalid(field)) => prop_assert!(!field.field.is_empty(), "{field}"),
            Err(e) => prop_assert!(!robocal::error::chain(&e).is_empty()),
        }
    }
}

proptest! {
    #![proptest_config(config(40))]

    /// `calibrate --select` (t, bic, cv) with a robust loss on a few poses of the example,
    /// their values mutated: a selection or an error, never a panic.
    #[test]
    fn selection_with_any_loss_never_panics(
        mutations in prop::collection::vec(mutation(), 0..3),
        criterion in 0usize..3,
        folds in 0usize..5,
        loss in loss(),
    ) {
        use robocal::calibration::{front::Kinds, selection::{Criterion, select}};
        let Ok(data) = KindData::from_csv_str(&mutate(&head(MEASUREMENTS, 12), &mutations), &puma(), None) else {
            return Ok(());
        };
        let criterion = [Criterion::T, Criterion::Bic, Criterion::Cv { folds }][criterion];
        let mut options = quick_options(&puma(), loss, Vec::new());
        options.joints = JointParams::Named(vec!["j2.*".into(), "j3.a".into()]);
        let _ = select(&Kinds(&puma()), &data, &options, criterion);
    }
}
