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
    &["pipeline"],
];

fn level(module: &str) -> Option<usize> {
    LEVELS.iter().position(|level| level.contains(&module))
}

/// Every top-level module a text uses by `crate::name`, including those inside
/// `crate::{a, b::c}` over several lines.
fn used_modules(text: &str) -> Vec<String> {
    text.match_indices("crate::").flat_map(|(i, _)| names_after(&text[i + "crate::".len()..])).collect()
}

/// The top-level modules that `super::` chains reach from the module at `path` (its names from
/// the crate root: `["calibration", "kinds", "data"]`): a chain of `k` supers climbs `k`
/// levels; one that reaches the crate root names a top-level module, any other stays in the
/// file's own. Chains that climb above the root (an inline `mod tests`) are left out.
fn super_modules(text: &str, path: &[String]) -> Vec<(usize, String)> {
    let mut used = Vec::new();
    for (start, climbs, rest) in super_chains(text) {
        let names = match path.len().checked_sub(climbs) {
            Some(0) => names_after(rest),
            Some(_) => vec![path[0].clone()],
            None => Vec::new(),
        };
        used.extend(names.into_iter().map(|m| (start, m)));
    }
    used
}

/// Each chain of `super::` in `text`: where it starts, how many levels it climbs, and the text
/// after it.
fn super_chains(text: &str) -> Vec<(usize, usize, &str)> {
    let mut chains = Vec::new();
    let mut at = 0;
    while let Some(i) = text[at..].find("super::") {
        let start = at + i;
        let mut rest = &text[start..];
        let mut climbs = 0;
        while let Some(r) = rest.strip_prefix("super::") {
            climbs += 1;
            rest = r;
        }
        at = text.len() - rest.len();
        chains.push((start, climbs, rest));
    }
    chains
}

/// The first name of the path after `crate::` or a chain of supers: of each item of a group
/// `{a, b::{c}}`, at the group's own depth.
fn names_after(rest: &str) -> Vec<String> {
    let mut used = Vec::new();
    if let Some(group) = rest.strip_prefix('{') {
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
    used.retain(|m| !m.is_empty() && m != "self");
    used
}

/// `text` without its `//` comments (doc comments too), lines kept.
fn without_comments(text: &str) -> String {
    text.lines().map(|l| l.find("//").map_or(l, |i| &l[..i])).collect::<Vec<_>>().join("\n")
}

/// The line (from 1) of byte `at` of `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at].matches('\n').count() + 1
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
        let text = without_comments(&std::fs::read_to_string(file).unwrap());
        let mut path: Vec<String> =
            relative.iter().map(|c| c.to_str().unwrap().trim_end_matches(".rs").to_string()).collect();
        if path.last().is_some_and(|l| l == "mod") {
            path.pop();
        }
        let mut found: Vec<(usize, String)> = (text.match_indices("crate::"))
            .flat_map(|(i, _)| names_after(&text[i + "crate::".len()..]).into_iter().map(move |m| (i, m)))
            .collect();
        found.extend(super_modules(&text, &path));
        for (at, used) in found {
            checked += 1;
            let allowed = used == module || level(&used).is_some_and(|l| l < own);
            if !allowed && level(&used).is_some() {
                violations.push(format!(
                    "src/{}:{}: `{module}` uses `{used}`",
                    relative.display(),
                    line_of(&text, at)
                ));
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
    // A group over several lines.
    assert_eq!(used_modules("use crate::{\n    model::A,\n    report::{B, C},\n};"), ["model", "report"]);
    // Supers: from calibration::kinds::data, two climb to calibration's own, three to the root.
    let path: Vec<String> = ["calibration", "kinds", "data"].map(String::from).to_vec();
    let first =
        |text: &str| -> Vec<String> { super_modules(text, &path).into_iter().map(|(_, m)| m).collect() };
    assert_eq!(first("use super::super::selection::X;"), ["calibration"]);
    assert_eq!(first("use super::super::super::report::Y;"), ["report"]);
    assert_eq!(first("use super::super::super::{io::A,\n simulation::B};"), ["io", "simulation"]);
    assert!(first("use super::super::super::super::x;").is_empty());
    assert_eq!(without_comments("a // crate::report\n/// crate::io\nb"), "a \n\nb");
}

/// The sibling modules of `calibration` (its files and folders, `mod.rs` its face) that the
/// module at `path` (its names from `calibration`: `["kinds", "data"]`; a folder's `mod.rs` is
/// the folder's) uses: by `crate::calibration::x`, or by the supers that climb to
/// `calibration` (one from a file of its own, two from a file in a folder).
fn calibration_siblings(text: &str, path: &[String]) -> Vec<String> {
    let mut used: Vec<String> = (text.match_indices("crate::calibration::"))
        .flat_map(|(i, _)| names_after(&text[i + "crate::calibration::".len()..]))
        .collect();
    for (_, climbs, rest) in super_chains(text) {
        if climbs == path.len() {
            used.extend(names_after(rest));
        }
    }
    used.retain(|m| *m != path[0]);
    used
}

/// A cycle of `edges` (`from -> to`), as the names along it, if there is one.
fn a_cycle(edges: &[(String, String)]) -> Option<Vec<String>> {
    fn visit(
        at: &str,
        edges: &[(String, String)],
        stack: &mut Vec<String>,
        done: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = stack.iter().position(|s| s == at) {
            return Some(stack[k..].iter().cloned().chain([at.to_string()]).collect());
        }
        if done.iter().any(|d| d == at) {
            return None;
        }
        stack.push(at.to_string());
        for (_, to) in edges.iter().filter(|(from, _)| from == at) {
            if let Some(cycle) = visit(to, edges, stack, done) {
                return Some(cycle);
            }
        }
        done.push(stack.pop().unwrap());
        None
    }
    let mut done = Vec::new();
    edges.iter().find_map(|(from, _)| visit(from, edges, &mut Vec::new(), &mut done))
}

/// The calibration's modules use each other one way: no cycle among its files and folders
/// (a folder, `kinds/`, is one module; `mod.rs` is the face that names them).
#[test]
fn the_calibrations_modules_use_each_other_one_way() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/calibration");
    let mut files = Vec::new();
    visit(&root, &mut files);
    let mut edges: Vec<(String, String)> = Vec::new();
    for file in &files {
        let mut path: Vec<String> = (file.strip_prefix(&root).unwrap().iter())
            .map(|c| c.to_str().unwrap().trim_end_matches(".rs").to_string())
            .collect();
        if path.len() > 1 && path.last().is_some_and(|l| l == "mod") {
            path.pop();
        }
        if path == ["mod"] {
            continue;
        }
        let siblings = |name: &String| root.join(format!("{name}.rs")).exists() || root.join(name).is_dir();
        let text = without_comments(&std::fs::read_to_string(file).unwrap());
        for used in calibration_siblings(&text, &path).into_iter().filter(siblings) {
            if !edges.contains(&(path[0].clone(), used.clone())) {
                edges.push((path[0].clone(), used));
            }
        }
    }
    assert!(edges.len() > 15, "too few uses read ({}): is it reading src/calibration?", edges.len());
    assert_eq!(a_cycle(&edges), None, "a cycle among the calibration's modules");
    // The check finds one.
    let looped = [("a", "b"), ("b", "c"), ("c", "a")].map(|(a, b)| (a.to_string(), b.to_string()));
    assert_eq!(a_cycle(&looped).unwrap(), ["a", "b", "c", "a"]);
    let path: Vec<String> = ["kinds", "data"].map(String::from).to_vec();
    assert_eq!(
        calibration_siblings("use super::super::{selection::X,\n front::Y};", &path),
        ["selection", "front"]
    );
    assert!(calibration_siblings("use super::camera::Z;", &path).is_empty(), "inside its own folder");
}

/// The longest function a module of the calibration may have: a longer one is several steps
/// that want names of their own.
const MAX_FUNCTION_LINES: usize = 80;

/// Each function of `text` (`fn` at the start of a line, after any `pub`, `const` or
/// `unsafe`) with its first line (from 1) and its length in lines, from its `fn` line to the
/// line that closes its body. Comments, strings and character literals do not count braces.
fn function_lengths(text: &str) -> Vec<(usize, String, usize)> {
    let lines: Vec<String> = without_comments(text).lines().map(without_literals).collect();
    let mut found = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some(name) = fn_name(&lines[i]) else {
            i += 1;
            continue;
        };
        let (mut depth, mut opened, mut end) = (0i64, false, None);
        for (j, line) in lines.iter().enumerate().skip(i) {
            depth += line.matches('{').count() as i64 - line.matches('}').count() as i64;
            opened |= line.contains('{');
            if (opened && depth <= 0) || (!opened && line.contains(';')) {
                end = Some(j);
                break;
            }
        }
        let end = end.unwrap_or(lines.len() - 1);
        if opened {
            found.push((i + 1, name, end - i + 1));
        }
        i = end + 1;
    }
    found
}

/// The name of the function a line declares, if it does.
fn fn_name(line: &str) -> Option<String> {
    let mut rest = line.trim_start();
    for prefix in ["pub(crate) ", "pub(super) ", "pub ", "const ", "unsafe ", "async "] {
        rest = rest.strip_prefix(prefix).unwrap_or(rest);
    }
    rest.strip_prefix("fn ").map(first_name)
}

/// `line` with its string and character literals emptied (their braces are not code).
fn without_literals(line: &str) -> String {
    let mut out = String::new();
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' => {
                while let Some(d) = chars.next() {
                    match d {
                        '\\' => {
                            chars.next();
                        }
                        '"' => break,
                        _ => {}
                    }
                }
                out.push_str("\"\"");
            }
            '\'' if chars.clone().nth(1) == Some('\'') || chars.peek() == Some(&'\\') => {
                // A character literal ('{', '\n'); a lifetime ('a) is left as it is.
                for d in chars.by_ref() {
                    if d == '\'' {
                        break;
                    }
                }
                out.push_str("' '");
            }
            c => out.push(c),
        }
    }
    out
}

#[test]
fn no_function_of_the_library_is_over_80_lines() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    visit(&dir, &mut files);
    let mut seen = 0;
    let mut long = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for (line, name, length) in function_lengths(&text) {
            seen += 1;
            if length > MAX_FUNCTION_LINES {
                long.push(format!("{}:{line}: `{name}` is {length} lines", file.display()));
            }
        }
    }
    assert!(seen > 1000, "the check read too few functions ({seen}): is it reading src?");
    assert!(long.is_empty(), "functions over {MAX_FUNCTION_LINES} lines:\n{}", long.join("\n"));
}

#[test]
fn the_length_check_counts_bodies_not_braces_in_text() {
    let text = "pub(crate) fn a(x: u8) -> u8 {\n    let s = \"{{\"; let c = '{';\n    x\n}\n\
                fn declared(&self);\nfn b<'a>(v: &'a str) {\n    // }\n    if true {\n    }\n}\n";
    assert_eq!(function_lengths(text), [(1, "a".to_string(), 4), (6, "b".to_string(), 5)]);
}
