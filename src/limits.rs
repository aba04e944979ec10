//! The bounds of every size and magnitude an input controls, in one place, so that no file or
//! flag can make robocal allocate without bound, loop for ever, or carry a number whose
//! square overflows into a factorisation. The readers and the command line refuse a value
//! beyond them with an error naming the field; `docs/formats.md` lists them.
//!
//! The sizes are far above any real calibration campaign or study (the paper's largest case
//! has 192 points; a laser-tracker campaign a few thousand poses), and far below what would
//! overflow a count or an allocation. The memory a command will need is estimated from them
//! by formulas next to the code that allocates ([`crate::simulation::Study::memory_estimate`],
//! [`crate::design::Design::plan_memory_estimate`]) and checked against the machine by
//! `io::check_memory` before anything large is allocated.

/// Joints of a model (model TOML, URDF chain).
pub const MAX_JOINTS: usize = 64;

/// Measurement points per case of a study, and poses of `plan --points`.
pub const MAX_POINTS: usize = 1_000_000;

/// Candidate poses of `plan --candidates` and of a study's `[design]`.
pub const MAX_CANDIDATES: usize = 1_000_000;

/// Test configurations of a study (`test_points`).
pub const MAX_TEST_POINTS: usize = 1_000_000;

/// Cases of a study: `points` x `sigma_me_mm` x `design.poses`.
pub const MAX_CASES: usize = 10_000;

/// Point sets per case, and runs per point set, of a study.
pub const MAX_RUNS_PER_CASE: usize = 1_000_000;

/// Runs of a whole study: cases x point sets x runs per set.
pub const MAX_RUNS: usize = 10_000_000;

/// The work of a whole study, in evaluations of the kinematics: the sum over its runs of the
/// points and the test points (the paper's two studies: under 1e6). Beyond it a study would
/// run for days: refused rather than left to look hung.
pub const MAX_STUDY_WORK: u64 = 10_000_000_000;

/// The work of `plan`, in products of Jacobian rows and parameters in one pass of its
/// exchange (candidates x points x rows a pose x parameters): beyond it, hours of work,
/// refused with the estimate. Measured on two shared cores: about 1e8 a second; 9.7e9 (a
/// million candidates, 140 points) took 37.5 min in 10 passes, with a progress bar and each
/// pass's time left (the number of passes is not known in advance).
pub const MAX_WORK: u64 = 10_000_000_000;

/// The work of an instrument study, in products of Jacobian rows and parameters fitted (runs x
/// observations x 3 rows x parameters, summed over the instruments; each is refitted several
/// times): the `instruments` study is about 2e7 and takes minutes; beyond 1e9, hours,
/// refused with the estimate.
pub const MAX_INSTRUMENT_WORK: u64 = 1_000_000_000;

/// Gauss-Newton steps (`calibrate --iterations`, a study's `iterations`).
pub const MAX_ITERATIONS: usize = 1_000;

/// Bins of a histogram figure: wider bins beyond it.
pub const MAX_BINS: usize = 200;

/// The largest length, coordinate or length sigma, in mm (1 km): model lengths, tool and
/// marker positions, measured coordinates, `sigma_mm` and the like. Its square (1e12) and the
/// sums of squares of a large problem stay far from overflow.
pub const MAX_LENGTH_MM: f64 = 1e6;

/// The largest angle or angle sigma in degrees: model angles and joint limits, joint values,
/// joint sigmas in degrees (almost three turns).
pub const MAX_ANGLE_DEG: f64 = 1e3;

/// The largest mass, in kg (100 t): a link's (`[[links]] mass_kg`, a URDF `<inertial>`), a
/// payload's (`[payload]`, `--payload-kg`, `[truth] payload_kg`). Centres of mass are lengths
/// ([`MAX_LENGTH_MM`]).
pub const MAX_MASS_KG: f64 = 1e5;

/// The largest joint compliance: rad/(N·m) for a revolute joint, mm/N for a prismatic one (a
/// joint turning a radian under one N·m is no joint). A study's true compliances are at least
/// 0; a model's are bounded in magnitude, as a calibrated model may carry a negative estimate.
pub const MAX_COMPLIANCE: f64 = 1.0;

/// The largest magnitude of a joint's play: deg for a revolute joint, mm for a prismatic one.
pub const MAX_PLAY: f64 = 10.0;

/// The smallest prior standard deviation, in the parameter's unit (mm, rad, rad/(N·m) or
/// mm/N): a parameter held at its nominal value to 1e-15 (its prior row's weight, about
/// `sigma / sd`, stays far from overflow).
pub const MIN_PRIOR_SD: f64 = 1e-15;

/// The largest prior standard deviation, in the parameter's unit: no prior at all, to rounding.
pub const MAX_PRIOR_SD: f64 = 1e12;

/// The smallest standard deviation above zero a study takes, in its field's unit (mm for
/// `sigma_me_mm`, deg for `joint_sigma` and `sigma_orientation_deg`): 0 is an exact quantity,
/// and a picometre or a nano-degree is far below any instrument; a subnormal one such as
/// `4e-320` would make its weights overflow and its figures' names 300 digits long.
pub const MIN_SIGMA: f64 = 1e-9;

/// `Err(message)` unless `value` is finite and within `[low, high]`.
pub fn check_range(value: f64, low: f64, high: f64, unit: &str) -> Result<f64, String> {
    if value.is_finite() && (low..=high).contains(&value) {
        Ok(value)
    } else {
        Err(format!("a number from {} to {} {unit}, found {}", shown(low), shown(high), shown(value)))
    }
}

/// The share of the machine's memory (its total memory, or the process's address-space limit
/// if lower) that a command may plan to use.
pub const MEMORY_SHARE: f64 = 0.5;

/// The memory assumed when the machine's cannot be read (bytes, 4 GiB).
pub const FALLBACK_MEMORY: u64 = 4 << 30;

/// `Err(message)` unless `value` is finite and its magnitude at most `bound`.
pub fn check_magnitude(value: f64, bound: f64, unit: &str) -> Result<f64, String> {
    if value.is_finite() && value.abs() <= bound {
        Ok(value)
    } else {
        Err(format!("a finite number of magnitude at most {bound:e} {unit}, found {}", shown(value)))
    }
}

/// `value` as a person reads it: `1e300` rather than its 301 digits.
pub fn shown(value: f64) -> String {
    if value != 0.0 && value.is_finite() && !(1e-4..1e7).contains(&value.abs()) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// `Err(message)` unless `count` is at most `bound`.
pub fn check_count(count: usize, bound: usize) -> Result<usize, String> {
    if count <= bound { Ok(count) } else { Err(format!("at most {bound}, found {count}")) }
}

/// Serde's `[f64; N]` from exactly `N` numbers: serde's own array reads the first `N` and
/// lets more pass unseen (`limits_deg = [-10, 10, 30]`). For `#[serde(deserialize_with)]`.
pub(crate) fn exactly<'de, D: serde::Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    let values = <Vec<f64> as serde::Deserialize>::deserialize(d)?;
    let found = values.len();
    values.try_into().map_err(|_| serde::de::Error::invalid_length(found, &format!("{N} numbers").as_str()))
}

/// [`exactly`] for `N` arrays of exactly `M` numbers each (`stations_mm = [[x, y, z], [x, y, z]]`).
pub(crate) fn exactly_nested<'de, D: serde::Deserializer<'de>, const N: usize, const M: usize>(
    d: D,
) -> Result<[[f64; M]; N], D::Error> {
    let rows = <Vec<Vec<f64>> as serde::Deserialize>::deserialize(d)?;
    let found = rows.len();
    let rows = rows
        .into_iter()
        .map(|row| {
            let n = row.len();
            <[f64; M]>::try_from(row).map_err(|_| {
                serde::de::Error::invalid_length(n, &format!("{M} numbers in each array").as_str())
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    rows.try_into().map_err(|_| serde::de::Error::invalid_length(found, &format!("{N} arrays").as_str()))
}

/// [`exactly`] for an optional field (with `#[serde(default)]`).
pub(crate) fn exactly_if_given<'de, D: serde::Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Option<[f64; N]>, D::Error> {
    exactly(d).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magnitudes_and_counts_are_bounded() {
        assert_eq!(check_magnitude(-5.0, MAX_LENGTH_MM, "mm"), Ok(-5.0));
        assert_eq!(
            check_magnitude(2e6, MAX_LENGTH_MM, "mm").unwrap_err(),
            "a finite number of magnitude at most 1e6 mm, found 2000000"
        );
        assert!(check_magnitude(f64::NAN, MAX_ANGLE_DEG, "deg").is_err());
        assert_eq!(check_count(3, 2).unwrap_err(), "at most 2, found 3");
    }
}
