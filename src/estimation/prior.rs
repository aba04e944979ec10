//! Priors on the parameter errors: maximum a posteriori (MAP) estimation.
//!
//! A prior says how far from the nominal model a parameter is expected to be: its error `x_j`
//! has the prior `N(0, s_j^2)` (a machining tolerance, say), independently of the others. With
//! the measurements `y = H x + e`, `e ~ N(0, V)`, the posterior mode minimises
//!
//! ```text
//! J(x) = (y - H x)^T V^-1 (y - H x) + sum_j (x_j / s_j)^2
//! ```
//!
//! which is a least-squares problem of its own: the whitened rows of the data, `S y = S H x`,
//! and one extra row per parameter with a prior, `0 = x_j / s_j + noise` (unit variance). The
//! estimators whiten the data with the paper's normalisation `S = sigma_max L^-1`
//! ([`super::Weights`]), so the prior rows are scaled by the same `c = sigma_max`:
//!
//! ```text
//! [ S H ]       [ S y ]
//! [ c P ] x  =  [  0  ],     P = diag(1 / s_j) over the parameters with a prior
//! ```
//!
//! Gauss-Newton runs on this stacked system, so Gauss-Markov stays exact. Its solution is
//! `x = (H^T V^-1 H + P^2)^-1 H^T V^-1 y`, and its covariance, with every stacked row of
//! covariance `c^2`, is the posterior one, `(H^T V^-1 H + P^2)^-1` ([`PriorRows`] gives the
//! information `c^2 P^2` the sandwich of a solve adds). For another estimator the data rows keep
//! their own covariance in the sandwich (`S V S^T`); OLS without a noise model takes `c` as the
//! residuals' spread of the fit without priors. A parameter without a prior has `1 / s_j = 0`:
//! no row.
//!
//! The priors are given as entries `PATTERN=VALUE[UNIT]` ([`PriorEntry`], see
//! `docs/formats.md`): a parameter name or pattern (`j*.alpha`, as `--params` takes them) or a
//! class of joint parameters (`lengths`, `angles`, `offsets`, `compliances`, `plays`), and a standard
//! deviation in `mm`, `um`, `deg`, `rad`, `mrad`, or for a compliance as a plain number in its
//! own unit (rad/N·m, mm/N). The unit also picks the parameters: `j*.*=0.1mm` puts a prior on
//! every length of the joints, `j*.*=0.05deg` on every angle (a play is an angle or a length
//! with its joint; the classes `lengths` and `angles` are the geometry's, not the plays; a
//! payload's mass takes no prior). Later entries override earlier
//! ones for the same parameter. [`PRESETS`] name typical tolerances.

use crate::limits::{MAX_PRIOR_SD, MIN_PRIOR_SD};
use crate::model::{ParamInfo, ParamKind, ParamOwner, ParamSet};
use nalgebra::{DMatrix, DVector};

/// What a prior entry's value is, by its unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PriorUnit {
    /// A length (mm inside).
    Length,
    /// An angle (rad inside).
    Angle,
    /// A compliance (rad/N·m for a revolute joint, mm/N for a prismatic one).
    Compliance,
}

/// One prior: the parameters it applies to and their standard deviation about the nominal model.
#[derive(Debug, Clone, PartialEq)]
pub struct PriorEntry {
    /// A parameter name or pattern (`j*.alpha`), or `lengths`, `angles`, `offsets`,
    /// `compliances`, `plays`: those of every joint.
    pub target: String,
    /// The standard deviation, in mm, rad, or the compliance's unit.
    pub sd: f64,
    /// Which parameters of the target it applies to.
    pub unit: PriorUnit,
    /// The entry as written, for messages.
    pub text: String,
}

/// Why priors could not be read or applied.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PriorError {
    /// An entry is not `PATTERN=VALUE[UNIT]` with a known unit and a positive value.
    #[error("prior `{entry}`: {expected}")]
    Syntax {
        /// The entry as written.
        entry: String,
        /// What was expected.
        expected: String,
    },
    /// An entry's target matches no parameter of its unit.
    #[error(
        "prior `{entry}`: no {what} parameter matches `{target}`; parameters are named like `j2.alpha`, \
         `shoulder.x` (patterns with `*`), or use `lengths`, `angles`, `offsets`, `compliances`, `plays`{}",
        if *what == "compliance" { " (a plain number is a compliance's: give a length or an angle its unit, `0.5mm`, `0.05deg`)" } else { "" }
    )]
    NoMatch {
        /// The entry as written.
        entry: String,
        /// Its target.
        target: String,
        /// `length`, `angle` or `compliance`.
        what: &'static str,
    },
}

/// Named sets of priors, `--prior NAME`, typical tolerances of an arm's geometry: on lengths,
/// on the angles between axes, and on the joint zeros (deg for a revolute joint, mm for a
/// prismatic one), which encoders are mounted with. `machined`: a machined, assembled arm
/// (0.1 mm, 0.05 deg, 0.5 deg); `precision`: ground and fitted parts, zeros set by a fixture
/// (0.02 mm, 0.01 deg, 0.1 deg); `fabricated`: welded or cast and lightly machined (0.5 mm,
/// 0.2 deg, 2 deg). Each also bounds a joint's play, the backlash of its gears (0.02 deg,
/// 0.005 deg, 0.1 deg; the same number in mm for a prismatic joint): without it, a play and its
/// joint's zero, which its prior holds near nominal, trade places wherever the load keeps one
/// sign, and poses where it turns over pay for it. None puts a prior on the compliances (they
/// have no nominal value to be near).
pub const PRESETS: [(&str, &str); 3] = [
    ("machined", "lengths=0.1mm,angles=0.05deg,offsets=0.5deg,offsets=0.5mm,plays=0.02deg,plays=0.02mm"),
    ("precision", "lengths=0.02mm,angles=0.01deg,offsets=0.1deg,offsets=0.1mm,plays=0.005deg,plays=0.005mm"),
    ("fabricated", "lengths=0.5mm,angles=0.2deg,offsets=2deg,offsets=2mm,plays=0.1deg,plays=0.1mm"),
];

impl PriorEntry {
    /// Parse `TARGET=VALUE[UNIT]`.
    pub fn parse(text: &str) -> Result<Self, PriorError> {
        let syntax =
            |expected: &str| PriorError::Syntax { entry: text.to_string(), expected: expected.to_string() };
        let (target, value) = text.split_once('=').ok_or_else(|| {
            syntax(
                "expected PATTERN=VALUE with a unit, e.g. `j*.alpha=0.05deg`, or a preset (`machined`, \
                 `precision`, `fabricated`)",
            )
        })?;
        let (target, value) = (target.trim(), value.trim());
        if target.is_empty() {
            return Err(syntax("expected a parameter name or pattern before `=`"));
        }
        let split = value.find(|c: char| !(c.is_ascii_digit() || "+-.eE".contains(c))).unwrap_or(value.len());
        // `1e-3` is a number, `1mm` a number and a unit: the exponent's `e` is part of the number.
        let (number, unit) = value.split_at(split);
        let number: f64 = number
            .parse()
            .map_err(|_| syntax("expected a number and a unit after `=`, e.g. `0.5mm`, `0.05deg`"))?;
        let (scale, unit) = match unit.trim() {
            "mm" => (1.0, PriorUnit::Length),
            "um" | "µm" => (1e-3, PriorUnit::Length),
            "m" => (1e3, PriorUnit::Length),
            "deg" => (1f64.to_radians(), PriorUnit::Angle),
            "rad" => (1.0, PriorUnit::Angle),
            "mrad" => (1e-3, PriorUnit::Angle),
            "" | "rad/N·m" | "rad/Nm" | "rad/N.m" | "mm/N" => (1.0, PriorUnit::Compliance),
            other => {
                return Err(syntax(&format!(
                    "unknown unit `{other}`: expected mm, um, m, deg, rad, mrad, or for a compliance a plain \
                     number (rad/N·m, mm/N)"
                )));
            }
        };
        let sd = number * scale;
        if !(sd.is_finite() && sd > 0.0) {
            return Err(syntax("expected a standard deviation above 0"));
        }
        if !(MIN_PRIOR_SD..=MAX_PRIOR_SD).contains(&sd) {
            let unit_name = match unit {
                PriorUnit::Length => "mm",
                PriorUnit::Angle => "rad",
                PriorUnit::Compliance => "rad/N·m or mm/N",
            };
            return Err(syntax(&format!(
                "a standard deviation from {} to {} {unit_name}, found {} {unit_name} (docs/formats.md#limits)",
                crate::limits::shown(MIN_PRIOR_SD),
                crate::limits::shown(MAX_PRIOR_SD),
                crate::limits::shown(sd)
            )));
        }
        // A class names its unit: `lengths` in a length unit, `angles` in an angle unit.
        let class_unit = match target {
            "lengths" => Some((PriorUnit::Length, "a length unit (mm, um, m)")),
            "angles" => Some((PriorUnit::Angle, "an angle unit (deg, rad, mrad)")),
            "compliances" => Some((PriorUnit::Compliance, "a plain number (rad/N·m, mm/N)")),
            _ => None,
        };
        if let Some((_, expected)) = class_unit.filter(|(u, _)| *u != unit) {
            return Err(syntax(&format!("`{target}` takes {expected}")));
        }
        Ok(Self { target: target.to_string(), sd, unit, text: text.to_string() })
    }

    /// Parse a list: entries separated by commas, each an entry or a preset's name.
    pub fn parse_list(text: &str) -> Result<Vec<Self>, PriorError> {
        let mut out = Vec::new();
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match PRESETS.iter().find(|(name, _)| *name == part) {
                Some((_, entries)) => out.extend(Self::parse_list(entries)?),
                None => out.push(Self::parse(part)?),
            }
        }
        Ok(out)
    }

    /// Whether the entry applies to parameter `p`: its target names it, or names its class,
    /// and its unit is `p`'s kind.
    fn applies_to(&self, p: &ParamInfo) -> bool {
        let kind = match (p.kind, p.unit()) {
            (ParamKind::Compliance, _) => PriorUnit::Compliance,
            (_, "rad") => PriorUnit::Angle,
            (_, "mm") => PriorUnit::Length,
            // a payload's mass (kg) takes no prior
            _ => return false,
        };
        if kind != self.unit {
            return false;
        }
        let joint = matches!(p.owner, ParamOwner::Joint(_));
        match self.target.as_str() {
            "lengths" | "angles" => joint && !p.is_offset && !p.is_load_response(),
            "offsets" => joint && p.is_offset,
            "compliances" => joint && p.kind == ParamKind::Compliance,
            "plays" => joint && p.kind == ParamKind::Play,
            pattern => crate::model::name_matches(pattern, &p.name),
        }
    }
}

/// The prior standard deviation of every parameter of `params` (full vector; infinite for
/// none) from `entries`, later entries overriding earlier ones. An entry whose name or pattern
/// applies to no parameter is an error (a class, `offsets=0.5mm`, may find none: a robot
/// without a prismatic joint).
pub fn prior_sds(entries: &[PriorEntry], params: &ParamSet) -> Result<Vec<f64>, PriorError> {
    prior_sds_of(entries, &params.iter().collect::<Vec<_>>())
}

/// [`prior_sds`] of the parameters `params` (a tree's, say, which are no one chain's set).
pub fn prior_sds_of(entries: &[PriorEntry], params: &[&ParamInfo]) -> Result<Vec<f64>, PriorError> {
    let mut sd = vec![f64::INFINITY; params.len()];
    for entry in entries {
        let mut matched = false;
        for (i, &p) in params.iter().enumerate() {
            if entry.applies_to(p) {
                sd[i] = entry.sd;
                matched = true;
            }
        }
        let class = ["lengths", "angles", "offsets", "compliances", "plays"].contains(&entry.target.as_str());
        if !matched && !class {
            let what = match entry.unit {
                PriorUnit::Length => "length",
                PriorUnit::Angle => "angle",
                PriorUnit::Compliance => "compliance",
            };
            return Err(PriorError::NoMatch {
                entry: entry.text.clone(),
                target: entry.target.clone(),
                what,
            });
        }
    }
    Ok(sd)
}

/// The entry of `entries` that sets each parameter's prior in [`prior_sds_of`] (the last that
/// applies to it), by index; `None` for a parameter without a prior. What sorts a preset's
/// parameters into its classes (`lengths`, `angles`, `offsets`, `plays`, `compliances`: the
/// entries' targets).
pub fn prior_entry_of(entries: &[PriorEntry], params: &[&ParamInfo]) -> Vec<Option<usize>> {
    (params.iter()).map(|&p| (0..entries.len()).rev().find(|&e| entries[e].applies_to(p))).collect()
}

/// The prior rows `c P` of a problem's columns: `weights[j] = c / s_j` (0 without a prior), and
/// the scale `c` of the whitened data rows.
#[derive(Debug, Clone, PartialEq)]
pub struct PriorRows {
    weights: Vec<f64>,
    scale: f64,
}

impl PriorRows {
    /// The rows of prior standard deviations `sd` (one per column; infinite: none) for data
    /// whitened to a standard deviation `scale` per row.
    pub fn new(sd: &[f64], scale: f64) -> Self {
        Self { weights: sd.iter().map(|s| if s.is_finite() { scale / s } else { 0.0 }).collect(), scale }
    }

    /// These rows weighing against `spread` instead of the data rows' `scale`: each weight
    /// `spread / s_j` (the residuals' standard deviation where the noise was a guess, so that a
    /// prior weighs against the data's own noise), the information still that of rows of
    /// standard deviation `scale`, so that the covariance scaled by `(spread / scale)^2` with
    /// the data's is the posterior `spread^2 (A^T A + P^T P)^-1`; as they are without one
    /// (`None`: the noise known, the rows' own `scale`).
    pub fn weighed_against(mut self, spread: Option<f64>) -> Self {
        let Some(spread) = spread else { return self };
        let ratio = spread / self.scale;
        self.weights.iter_mut().for_each(|w| *w *= ratio);
        self
    }

    /// Whether no column has a prior.
    pub fn is_empty(&self) -> bool {
        self.weights.iter().all(|&w| w == 0.0)
    }

    /// Number of columns.
    pub fn columns(&self) -> usize {
        self.weights.len()
    }

    /// The rows for `columns` (ascending) of these.
    pub fn select(&self, columns: &[usize]) -> Self {
        Self { weights: columns.iter().map(|&j| self.weights[j]).collect(), scale: self.scale }
    }

    /// `|c P x|^2`: the prior's part of the cost at `x`.
    pub fn cost(&self, x: &DVector<f64>) -> f64 {
        self.weights.iter().zip(x.iter()).map(|(w, x)| (w * x).powi(2)).sum()
    }

    /// `[a; c P]` and `[b; -c P x]`: the system linearised about `x` with the prior rows below
    /// (one per column with a prior).
    pub fn augment(
        &self,
        a: &DMatrix<f64>,
        b: &DVector<f64>,
        x: &DVector<f64>,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let with: Vec<usize> = (0..self.weights.len()).filter(|&j| self.weights[j] > 0.0).collect();
        let (m, p) = a.shape();
        let mut augmented = DMatrix::zeros(m + with.len(), p);
        augmented.rows_mut(0, m).copy_from(a);
        let mut rhs = DVector::zeros(m + with.len());
        rhs.rows_mut(0, m).copy_from(b);
        for (r, &j) in with.iter().enumerate() {
            augmented[(m + r, j)] = self.weights[j];
            rhs[m + r] = -self.weights[j] * x[j];
        }
        (augmented, rhs)
    }

    /// The information the prior rows add to the sandwich of a solve, `(c P)^T c^2 (c P)`:
    /// each row's covariance is `c^2` (a prior draw, whitened and scaled like the data).
    pub fn information(&self) -> DMatrix<f64> {
        DMatrix::from_diagonal(&DVector::from_iterator(
            self.weights.len(),
            self.weights.iter().map(|w| (w * self.scale).powi(2)),
        ))
    }

    /// `c`, the standard deviation of a whitened data row.
    pub fn scale(&self) -> f64 {
        self.scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::RobotModel;

    #[test]
    fn entries_parse_with_their_units() {
        let e = PriorEntry::parse("j*.alpha=0.05deg").unwrap();
        assert_eq!((e.target.as_str(), e.unit), ("j*.alpha", PriorUnit::Angle));
        assert!((e.sd - 0.05f64.to_radians()).abs() < 1e-15);
        assert_eq!(PriorEntry::parse("j2.a = 5um").unwrap().sd, 5e-3);
        assert_eq!(PriorEntry::parse("j2.compliance=1e-4").unwrap().unit, PriorUnit::Compliance);
        assert_eq!(PriorEntry::parse("j2.compliance=2e-4rad/N·m").unwrap().sd, 2e-4);
        let err = |t: &str| PriorEntry::parse(t).unwrap_err().to_string();
        assert!(err("j*.a").contains("expected PATTERN=VALUE"), "{}", err("j*.a"));
        assert!(err("j*.a=0.5inch").contains("unknown unit `inch`"), "{}", err("j*.a=0.5inch"));
        assert!(err("j*.a=-1mm").contains("above 0"));
        assert!(err("j*.a=mm").contains("expected a number"));
        assert_eq!(PriorEntry::parse_list("machined, j1.theta=1deg").unwrap().len(), 7);
        let precision = PriorEntry::parse_list("precision").unwrap();
        assert_eq!((precision[0].target.as_str(), precision[0].sd), ("lengths", 0.02));
        assert!(err("machind").contains("or a preset (`machined`"), "{}", err("machind"));
        // A class names its unit.
        assert!(err("lengths=0.1deg").contains("`lengths` takes a length unit"), "{}", err("lengths=0.1deg"));
        assert!(err("angles=0.1mm").contains("`angles` takes an angle unit"), "{}", err("angles=0.1mm"));
        assert!(err("compliances=1mm").contains("`compliances` takes a plain number"));
    }

    #[test]
    fn entries_apply_by_unit_and_later_ones_win() {
        let params = RobotModel::preset("puma560").unwrap().params();
        let entries = PriorEntry::parse_list("machined,j2.a=1mm").unwrap();
        let sd = prior_sds(&entries, &params).unwrap();
        let at = |name: &str| sd[params.index_by_name(name).unwrap()];
        assert_eq!(at("j2.a"), 1.0);
        assert_eq!(at("j3.a"), 0.1);
        assert!((at("j1.theta") - 0.5f64.to_radians()).abs() < 1e-15);
        assert!((at("j4.beta") - 0.05f64.to_radians()).abs() < 1e-15);
        assert!(at("base.x").is_infinite() && at("tool.z").is_infinite());
        let wrong = PriorEntry::parse_list("j*.a=0.05deg").unwrap();
        assert_eq!(
            prior_sds(&wrong, &params).unwrap_err(),
            PriorError::NoMatch { entry: "j*.a=0.05deg".into(), target: "j*.a".into(), what: "angle" }
        );
    }

    /// A noise file's `[prior]` table: the more specific entry last, read back as written; a
    /// bad value names its field.
    #[test]
    fn a_noise_files_prior_table_reads_and_writes() {
        let model = RobotModel::preset("puma560-masses").unwrap();
        let text = "joint_sigma = [0.01, 0.01, 0.01, 0.01, 0.01, 0.01]\n[prior]\n\"j2.a\" = \"1mm\"\n\
                    \"j*.a\" = \"0.2mm\"\n\"j6.play\" = \"0.1deg\"\nlengths = \"0.1mm\"\nplays = \"0.005deg\"\n";
        let spec = crate::estimation::NoiseSpec::from_toml_str(text, &model).unwrap();
        let targets: Vec<&str> = spec.prior.iter().map(|e| e.target.as_str()).collect();
        assert_eq!(targets, ["lengths", "plays", "j*.a", "j2.a", "j6.play"]);
        let sd = prior_sds(&spec.prior, &model.params()).unwrap();
        assert_eq!(sd[model.params().index_by_name("j2.a").unwrap()], 1.0);
        let play = sd[model.params().index_by_name("j6.play").unwrap()];
        assert!((play - 0.1f64.to_radians()).abs() < 1e-15, "the name wins over the class");
        let again =
            crate::estimation::NoiseSpec::from_toml_str(&spec.to_toml_string(&model, ""), &model).unwrap();
        assert_eq!(again.prior, spec.prior);
        let bad = "joint_sigma = [0.01, 0.01, 0.01, 0.01, 0.01, 0.01]\n[prior]\nlengths = \"1 inch\"\n";
        let err = crate::estimation::NoiseSpec::from_toml_str(bad, &model).unwrap_err();
        let crate::estimation::NoiseFileError::Invalid(field) = err else { panic!("{err:?}") };
        assert!(field.to_string().contains("prior.lengths"), "{field}");
    }

    #[test]
    fn augmented_rows_hold_the_prior() {
        let rows = PriorRows::new(&[2.0, f64::INFINITY], 0.5);
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1.0]);
        let b = DVector::from_vec(vec![1.0, 2.0]);
        let x = DVector::from_vec(vec![4.0, 3.0]);
        let (aa, bb) = rows.augment(&a, &b, &x);
        assert_eq!(aa.shape(), (3, 2));
        assert_eq!((aa[(2, 0)], aa[(2, 1)], bb[2]), (0.25, 0.0, -1.0));
        assert_eq!(rows.cost(&x), 1.0);
        assert_eq!(rows.information()[(0, 0)], 0.25f64.powi(2) * 0.25);
    }
}
