//! The library's modules depend one way: each may use only the modules below it (lib.rs
//! lists the order). A `use crate::x` (or `crate::x::...` anywhere) of a module at the same
//! level or above fails here, naming the file and the line.

use std::path::Path;

/// The modules from the bottom up; modules on one line are at the same level and do not use
/// each other.
const LEVELS: &[&[&str]] = &[
    &["error", "limits", "linalg"],
    &["model"],
    &["kinematics", "table"],
    &["estimation"],
    &["calibration", "design"],
    &["simulation"],
    &["io", "report"],
];

fn level(module: &str) -> Option<usize> {
    LEVELS.iter().position(|level| level.contains(&module))
}

/// Every `crate::name` a line uses, including those inside `crate::{a, b::c}`.
fn used_modules(line: &str) -> Vec<String> {
    let mut used = Vec::new();
    for (i, _) in line.match_indices("crate::") {
        let rest = &line[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            // the first name of each item at the group's own depth
            let (mut depth, mut item) = (0, String::new());
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => used.push(first_name(&std::mem::take(&mut item))),
                    c if depth == 0 => item.push(c),
                    _ => {}
                }
            }
            used.push(first_name(&item));
        } else {
            used.push(first_name(rest));
        }
    }
    used.retain(|m| !m.is_empty());
    used
}

/// The leading identifier of a path (`table` of `table::Units`).
fn first_name(path: &str) -> String {
    path.trim().chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect()
}

fn visit(dir: &Path, files: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            visit(&path, files);
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
}

#[test]
fn modules_use_only_the_modules_below_them() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    visit(&src, &mut files);
    let mut checked = 0;
    let mut violations = Vec::new();
    for file in &files {
        let relative = file.strip_prefix(&src).unwrap();
        let module =
            relative.components().next().unwrap().as_os_str().to_str().unwrap().trim_end_matches(".rs");
        let Some(own) = level(module) else { continue };
        let text = std::fs::read_to_string(file).unwrap();
        for (n, line) in text.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with("//")) {
            for used in used_modules(line) {
                checked += 1;
                let allowed = used == module || level(&used).is_some_and(|l| l < own);
                if !allowed && level(&used).is_some() {
                    violations.push(format!(
                        "src/{}:{}: `{module}` uses `{used}`",
                        relative.display(),
                        n + 1
                    ));
                }
            }
        }
    }
    assert!(checked > 50, "the check read too few `crate::` paths ({checked}): is it reading src/?");
    assert!(violations.is_empty(), "modules used from below:\n{}", violations.join("\n"));
}

#[test]
fn every_library_module_has_a_level() {
    let lib = include_str!("../../src/lib.rs");
    for line in lib.lines() {
        let Some(name) = line.trim().strip_prefix("pub mod ").or_else(|| line.trim().strip_prefix("mod "))
        else {
            continue;
        };
        let name = name.trim_end_matches(';');
        assert!(level(name).is_some(), "module `{name}` of lib.rs has no level in LEVELS");
    }
}

#[test]
fn the_check_sees_grouped_and_inline_paths() {
    assert_eq!(used_modules("use crate::{model::A, table::{B, C}};"), ["model", "table"]);
    assert_eq!(used_modules("let x = crate::simulation::run(s);"), ["simulation"]);
}
