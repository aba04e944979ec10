//! What a calibration report leads with: the verdict (per set, the marker error's RMS and max
//! before and after, the poses flagged, the warnings counted by cause), and what was held in
//! plain words, grouped by why, before the algebraic combinations. Typed, so that text, JSON
//! and HTML render the same data.

use crate::calibration::{Cause, Confounder, Held, Warning};
use serde::Serialize;
use std::fmt::Write;

/// The warnings of one cause, counted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarningCount {
    /// The cause (as `warnings[i].cause` names it).
    pub cause: Cause,
    /// The things it concerns: estimates past a bound, far-out observations; 1 for the others.
    pub count: usize,
    /// What it is about, in a few words (the warning in full is in `warnings`).
    pub about: String,
}

impl WarningCount {
    /// The count of `warning`.
    pub fn of(warning: &Warning) -> Self {
        Self { cause: warning.cause(), count: warning.count(), about: warning.headline() }
    }
}

/// One row of the verdict of observation files or a tree's views: one quantity of one set (a
/// group of observations, the markers' positions, one marker's, a view's position or
/// rotation), typed, as the text, the page and the JSON render it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QuantityRow {
    /// The set: `training`, a held-out file, the k-fold cross-validation.
    pub set: String,
    /// What of it: `distances`, `markers`, `marker 2`, `probe orientations`; empty where the
    /// set has one quantity of its unit (one kind of file).
    pub quantity: String,
    /// `mm` or `deg`.
    pub unit: &'static str,
    /// The observations (positions: a marker at a pose; views).
    pub count: usize,
    /// The RMS before and after calibration.
    pub rms: [f64; 2],
    /// The largest before and after.
    pub max: [f64; 2],
    /// Those flagged after calibration; none where another row of the same observations
    /// counts them (a view's rotation).
    pub flagged: Option<usize>,
}

impl QuantityRow {
    /// Its label: `training distances (mm)`, `training (deg)`.
    pub fn label(&self) -> String {
        match self.quantity.is_empty() {
            true => format!("{} ({})", self.set, self.unit),
            false => format!("{} {} ({})", self.set, self.quantity, self.unit),
        }
    }

    /// Its cells in a verdict table: label, count, RMS and max before -> after (4 decimals in
    /// mm, 5 in deg), flagged.
    pub fn cells(&self) -> [String; 5] {
        let digits = if self.unit == "deg" { 5 } else { 4 };
        let pair = |v: [f64; 2]| format!("{:.digits$} -> {:.digits$} {}", v[0], v[1], self.unit);
        let flagged = self.flagged.map_or_else(String::new, |f| format!("{f} of {}", self.count));
        [self.label(), self.count.to_string(), pair(self.rms), pair(self.max), flagged]
    }
}

/// The verdict table of `rows` under `title`, the count's column headed `count`.
pub fn quantity_table(title: &str, count: &str, rows: &[QuantityRow]) -> String {
    let heading = ["set", count, "RMS", "max", "flagged"].map(String::from);
    let rows: Vec<[String; 5]> =
        std::iter::once(heading).chain(rows.iter().map(QuantityRow::cells)).collect();
    table(title, &rows)
}

/// A verdict's table under `title`: each row's label, count, RMS, max and flagged, the first row
/// the heading, in columns as wide as their widest cell.
pub(super) fn table(title: &str, rows: &[[String; 5]]) -> String {
    let width = |c: usize| rows.iter().map(|r| r[c].len()).max().unwrap_or(0);
    let w = [0, 1, 2, 3].map(width);
    let mut out = format!("{title}\n");
    for r in rows {
        let line = format!(
            "{:<a$}  {:>b$}  {:>c$}  {:>d$}  {}",
            r[0],
            r[1],
            r[2],
            r[3],
            r[4],
            a = w[0],
            b = w[1],
            c = w[2],
            d = w[3]
        );
        let _ = writeln!(out, "{}", line.trim_end());
    }
    out
}

/// The warnings counted by cause as text: `warnings: none`, or a line per cause with its count.
pub fn warnings_text(warnings: &[WarningCount]) -> String {
    if warnings.is_empty() {
        return "warnings: none\n".to_string();
    }
    let mut out = String::from("warnings by cause (in full at the end):\n");
    for w in warnings {
        let _ = writeln!(out, "  {:>4}  {}", w.count, w.about);
    }
    out
}

/// `warnings` counted by cause, as text ([`warnings_text`]).
pub fn count_warnings(warnings: &[Warning]) -> String {
    warnings_text(&warnings.iter().map(WarningCount::of).collect::<Vec<_>>())
}

/// Why a group of parameters is held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HeldReason {
    /// `--hold`.
    ByUser,
    /// No observation moves them.
    Unmoved,
    /// No observation can see them, for a reason the data give.
    Unseen,
    /// Of a combination the observations cannot tell apart.
    Combination,
    /// The robot's scale, which contacts alone cannot see.
    Scale,
    /// With the base estimated, they only move the whole robot.
    Base,
    /// With the markers estimated, they only move the markers.
    Markers,
    /// Held so that the parameters of `--keep` stay free.
    Keep,
    /// These poses cannot tell them from the others.
    Poses,
    /// Gravity does not load their joint.
    Unloaded,
}

/// Parameters held for one reason, in plain words.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldGroup {
    /// Why.
    pub reason: HeldReason,
    /// The parameters held, in the report's order.
    pub parameters: Vec<String>,
    /// Why, and what frees them, in words.
    pub words: String,
}

/// `held`'s reason and its words (the same for every parameter of a group).
fn reason(held: &Held) -> (HeldReason, String) {
    match held {
        Held::ByUser { setup: false, .. } => (HeldReason::ByUser, "held at their nominal values by --hold".into()),
        Held::ByUser { setup: true, .. } => (HeldReason::ByUser, "held at their start by --hold".into()),
        Held::Unmoved { .. } => (HeldReason::Unmoved, "the observations do not move them".into()),
        Held::Unseen { why, .. } => (HeldReason::Unseen, why.clone()),
        Held::Combination { .. } => {
            (HeldReason::Combination, "the observations cannot tell them from a combination of the others".into())
        }
        Held::Scale { .. } => (
            HeldReason::Scale,
            "held at their nominal values: contacts alone cannot see the robot's scale, which the longest length sets"
                .into(),
        ),
        Held::Unloaded { .. } => {
            (HeldReason::Unloaded, "gravity does not load their joints at these poses (a vertical axis?)".into())
        }
        Held::Confounded { with, .. } => match with {
            Confounder::Base => (
                HeldReason::Base,
                "with the base estimated they only move the whole robot: --fixed-base (if the measuring frame is \
                 the robot's) or --keep NAME frees one"
                    .into(),
            ),
            Confounder::Markers => (
                HeldReason::Markers,
                "with the markers estimated they only move the markers: --fixed-markers (if their positions are \
                 known) or --keep NAME frees one"
                    .into(),
            ),
            Confounder::Keep => (HeldReason::Keep, "held so that the parameters of --keep stay free".into()),
            Confounder::Poses => (
                HeldReason::Poses,
                "these poses cannot tell them from the others: vary the poses, or --keep NAME to hold another"
                    .into(),
            ),
        },
    }
}

/// `held` grouped by reason, the groups in the order of their first parameter.
pub fn held_groups(held: &[Held]) -> Vec<HeldGroup> {
    let mut groups: Vec<HeldGroup> = Vec::new();
    for h in held {
        let (reason, words) = reason(h);
        match groups.iter_mut().find(|g| g.reason == reason && g.words == words) {
            Some(group) => group.parameters.push(h.parameter().to_string()),
            None => groups.push(HeldGroup { reason, parameters: vec![h.parameter().to_string()], words }),
        }
    }
    groups
}

/// A held combination as algebra, the held parameter first (`j1.d - 0.5 base.z`); `None` for
/// a parameter held alone.
pub fn combination(held: &Held) -> Option<String> {
    match held {
        Held::Combination { parameter, terms } | Held::Confounded { parameter, terms, .. } => {
            Some(crate::estimation::combination_text(parameter, terms.iter().map(|(n, c)| (n.as_str(), *c))))
        }
        _ => None,
    }
}

/// What was held as text: the groups in plain words, then the combinations.
pub fn held_text(held: &[Held]) -> String {
    let mut out = String::new();
    if held.is_empty() {
        return out;
    }
    let _ = writeln!(out, "held fixed ({} parameter{}):", held.len(), if held.len() == 1 { "" } else { "s" });
    for g in held_groups(held) {
        let _ = writeln!(out, "  {}: {}", g.parameters.join(", "), g.words);
    }
    let combinations: Vec<String> = held.iter().filter_map(combination).collect();
    if !combinations.is_empty() {
        let _ = writeln!(
            out,
            "the combinations held (the held parameter first; the others' estimates absorb it):"
        );
        for c in combinations {
            let _ = writeln!(out, "  {c}");
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Held parameters group by reason in the order they come, and only combinations have
    /// algebra.
    #[test]
    fn held_parameters_group_by_reason() {
        let base = |p: &str| Held::Confounded {
            parameter: p.into(),
            terms: vec![("base.rz".into(), -1.0)],
            with: Confounder::Base,
        };
        let held = vec![
            base("j1.theta"),
            Held::ByUser { parameter: "j2.a".into(), setup: false },
            base("j1.beta"),
            Held::Unseen { parameter: "j3.d".into(), why: "one".into() },
            Held::Unseen { parameter: "j4.d".into(), why: "two".into() },
        ];
        let groups = held_groups(&held);
        let names: Vec<Vec<String>> = groups.iter().map(|g| g.parameters.clone()).collect();
        assert_eq!(names, [vec!["j1.theta", "j1.beta"], vec!["j2.a"], vec!["j3.d"], vec!["j4.d"]]);
        assert_eq!(groups[0].reason, HeldReason::Base);
        assert_eq!(combination(&held[0]).as_deref(), Some("j1.theta - base.rz"));
        assert_eq!(combination(&held[1]), None);
        let text = held_text(&held);
        assert!(text.starts_with("held fixed (5 parameters):\n  j1.theta, j1.beta: with the base"), "{text}");
        assert!(text.ends_with("absorb it):\n  j1.theta - base.rz\n  j1.beta - base.rz\n"), "{text}");
    }
}
