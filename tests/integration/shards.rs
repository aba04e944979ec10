//! `simulate --shard I/N` in separate processes, then `merge`: byte for byte the files of one
//! `simulate`, for the paper's two studies, a replicated study and an instrument study.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn robocal(args: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_robocal"));
    command.args(args);
    command
}

fn succeeded(output: Output) -> Output {
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    output
}

/// Every file of `folder`, by name.
fn files(folder: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        files.insert(path.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&path).unwrap());
    }
    files
}

/// A fresh temporary folder for `tag`.
fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("robocal-shards-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `simulate STUDY` once, and in 4 shards as 4 processes at once, merged: the same files.
fn shards_merge_to_the_single_run(study: &str, name: &str, extra: &[&str], dir: &Path) {
    let path = |p: &str| dir.join(p).to_string_lossy().into_owned();
    let single = path("single");
    let mut args = vec!["simulate", study, "--out", &single, "--threads", "1"];
    args.extend(extra);
    succeeded(robocal(&args).output().unwrap());
    let outs: Vec<String> = (0..4).map(|i| path(&format!("shard{i}"))).collect();
    let shards: Vec<String> = (0..4).map(|i| format!("{i}/4")).collect();
    let children: Vec<_> = (0..4)
        .map(|i| {
            let mut args =
                vec!["simulate", study, "--out", &outs[i], "--threads", "1", "--shard", &shards[i]];
            args.extend(extra);
            robocal(&args)
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        succeeded(child.wait_with_output().unwrap());
    }
    let merged = path("merged");
    let mut args = vec!["merge"];
    args.extend(outs.iter().map(String::as_str));
    args.extend(["--out", &merged]);
    let output = succeeded(robocal(&args).output().unwrap());
    let (expected, found) = (files(&dir.join("single").join(name)), files(&dir.join("merged").join(name)));
    assert!(expected.len() >= 2, "{:?}", expected.keys());
    assert_eq!(expected.keys().collect::<Vec<_>>(), found.keys().collect::<Vec<_>>());
    for (file, bytes) in &expected {
        assert!(bytes == &found[file], "{name}: {file} differs between the single run and the merged shards");
    }
    let tables = String::from_utf8(expected["tables.txt"].clone()).unwrap();
    assert!(String::from_utf8(output.stdout).unwrap().contains(&tables));
}

#[test]
fn merged_shards_of_the_paper_studies_are_the_single_run_byte_for_byte() {
    for name in ["paper-table1", "paper-table2"] {
        let dir = scratch(name);
        shards_merge_to_the_single_run(name, name, &[], &dir);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// A reduced paper-table2, its tables replicated 3 times.
fn reduced_study(dir: &Path) -> String {
    let text = robocal::simulation::STUDIES.iter().find(|(n, _)| *n == "paper-table2").unwrap().1;
    let text =
        text.replace("point_sets = 6", "point_sets = 2").replace("runs_per_set = 16", "runs_per_set = 5");
    assert!(text.contains("runs_per_set = 5"));
    let path = dir.join("reduced.toml");
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

#[test]
fn merged_shards_of_a_replicated_study_are_the_single_run_byte_for_byte() {
    let dir = scratch("replicated");
    let study = reduced_study(&dir);
    shards_merge_to_the_single_run(&study, "paper-table2", &["--replications", "3"], &dir);
    // A shard missing, or given twice, is named.
    let shard = |i: usize| dir.join(format!("shard{i}")).to_string_lossy().into_owned();
    let merged = dir.join("again").to_string_lossy().into_owned();
    let output = robocal(&["merge", &shard(0), &shard(1), &shard(3), "--out", &merged]).output().unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(!output.status.success() && stderr.contains("shards missing: 2/4"), "{stderr}");
    let output = robocal(&["merge", &shard(0), &shard(1), &shard(2), &shard(3), &shard(1), "--out", &merged])
        .output()
        .unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(!output.status.success() && stderr.contains("both are shard 1/4"), "{stderr}");
    assert!(!dir.join("again").exists());
    // A bad --shard is refused with what is expected.
    let output = robocal(&["simulate", &study, "--shard", "4/4"]).output().unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(output.status.code() == Some(2) && stderr.contains("0 <= I < N"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn merged_shards_of_an_instrument_study_are_the_single_run_byte_for_byte() {
    let dir = scratch("instruments");
    let text = robocal::simulation::INSTRUMENT_STUDIES.iter().find(|(n, _)| *n == "instruments").unwrap().1;
    let text = text.replace("runs = 200", "runs = 3").replace("test_points = 1000", "test_points = 50");
    assert!(text.contains("runs = 3"));
    let path = dir.join("instruments.toml");
    std::fs::write(&path, text).unwrap();
    shards_merge_to_the_single_run(path.to_str().unwrap(), "instruments", &[], &dir);
    std::fs::remove_dir_all(&dir).unwrap();
}
