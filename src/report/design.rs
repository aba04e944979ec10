//! Reports of pose design: the observability indices of a pose set, a planned set's summary.

use crate::design::{Design, Indices, Observability, Plan};
use std::fmt::Write;

/// A row of the indices table: its label and how to read it.
type Row = (&'static str, fn(&Indices) -> f64);

/// The indices of `observability` (of the poses in `source`), column-scaled and whitened side
/// by side, each with its formula.
pub fn observability(design: &Design, observability: &Observability, source: &str) -> String {
    let mut out = String::new();
    let measured = match design.measured() {
        crate::kinematics::Measured::Position => "position",
        crate::kinematics::Measured::Pose => "pose",
    };
    let _ = writeln!(
        out,
        "observability of {} poses ({source}) of {}: {} parameters, {} identifiable from {measured} measurements",
        observability.poses,
        design.model().name,
        observability.parameters,
        observability.identifiable
    );
    let _ = writeln!(
        out,
        "singular values of H D (column-scaled, identifiable columns) and S H D (whitened by V_k = J_k Sigma_q J_k^T + Sigma_m)"
    );
    let whitened = observability.whitened.as_ref();
    let _ = writeln!(out, "{:<44} {:>14} {:>14}", "index", "column-scaled", "whitened");
    let rows: [Row; 7] = [
        ("O1 (s_1 ... s_r)^(1/r) / sqrt(m)  Borm-Menq", |i| i.o1),
        ("O2 s_r / s_1          Driels-Pathre", |i| i.o2),
        ("O3 s_r                Nahvi et al.", |i| i.o3),
        ("O4 s_r^2 / s_1        Nahvi-Hollerbach", |i| i.o4),
        ("O5 1 / sum(1 / s_i)   Sun-Hollerbach", |i| i.o5),
        ("D  log det(H^T H) = 2 sum(ln s_i)", |i| i.log_det),
        ("condition number s_1 / s_r", |i| i.condition_number),
    ];
    for (name, value) in rows {
        let w = whitened.map_or("-".to_string(), |i| number(value(i)));
        let _ = writeln!(out, "{name:<44} {:>14} {w:>14}", number(value(&observability.scaled)));
    }
    let rank = whitened.map_or("-".to_string(), |i| i.rank.to_string());
    let _ = writeln!(out, "{:<44} {:>14} {rank:>14}", "rank", observability.scaled.rank);
    if whitened.is_none() {
        let _ = writeln!(out, "(no noise given: --joint-sigma-deg and --sigma-mm give the whitened indices)");
    }
    out
}

/// A number at 6 significant digits, in exponent form outside 1e-3..1e6.
fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if (1e-3..1e6).contains(&v.abs()) {
        let decimals = (5 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.5e}")
    }
}

/// What the planner did: the criterion before and after, the pool, the exchanges.
pub fn plan_summary(design: &Design, plan: &Plan, candidates: usize, draws: usize) -> String {
    let matrix = if design.weighted() { "whitened" } else { "column-scaled (no noise given)" };
    let mut out = String::new();
    let _ = writeln!(
        out,
        "planned {} poses of {} from {} candidates ({} usable, {} configurations drawn)",
        plan.joints.len(),
        design.model().name,
        candidates,
        plan.usable,
        draws
    );
    let _ = writeln!(
        out,
        "criterion {} on the {matrix} H of {} identifiable parameters: {} (the first {} candidates: {})",
        plan.criterion,
        design.identifiable().len(),
        number(plan.value),
        plan.joints.len(),
        number(plan.initial)
    );
    let _ = writeln!(out, "{} exchanges in {} passes", plan.exchanges, plan.passes);
    out
}
