//! Choosing the joint parameters by held-out error (`calibrate --select`).
//!
//! A real robot has errors no geometric model holds (deflection, backlash, a device's own
//! error); a fit that drives every weakly identified parameter absorbs them into terms the
//! training poses barely see, and loses on the poses it did not see. The candidates are the
//! joint parameters [`KindOptions::joints`](super::kinds::KindOptions::joints) names that the
//! poses identify (the calibration's gauge holds the others); the set-up (the base and the
//! markers, the registration) is always estimated. Three criteria:
//!
//! - [`Criterion::Cv`]: forward stepwise selection by `F`-fold cross-validation. Pose `k` is
//!   held out in fold `k mod F` (`k` numbered among the poses the data have, so that inside an
//!   outer fold no inner fold is empty). From the registration, each step adds the candidate whose
//!   model has the lowest cross-validated RMS
//!   `CV = sqrt(sum_f SSE_f / sum_f n_f)`, `SSE_f = sum |y_t - H_t x_f|^2` over the markers of
//!   fold `f`'s held-out poses (unweighted distances, mm; `n_f` markers), `x_f` the estimate
//!   from the other folds by the calibration's estimator. Its standard error is
//!   `SE = sd_f(RMS_f) / sqrt(F)` (`RMS_f = sqrt(SSE_f / n_f)`). The path runs until every
//!   candidate is in; the model chosen is the smallest whose CV is within one SE of the best
//!   step's (the one-standard-error rule, Hastie, Tibshirani and Friedman 2009, 7.10).
//! - [`Criterion::Bic`]: the same forward path, each step adding the candidate that lowers
//!   the whitened training cost `RSS = |S (y - H x)|^2` most, scored by
//!   `BIC = N ln(RSS / N) + p ln N` (`N` equations, `p` parameters with the registration's);
//!   the step of the lowest BIC is chosen.
//! - [`Criterion::T`]: backward elimination from every candidate: calibrate (Gauss-Newton, as
//!   [`calibrate_kinds`](super::kinds::calibrate_kinds)), drop the candidate of the smallest `|t| = |estimate| / SE` while it is
//!   below 2, and calibrate again.
//!
//! Each candidate is one parameter, for a URDF joint too: its origin's six numbers are not one
//! physical quantity, and the gauge holds some of them on their own (the turn about the joint's
//! axis, a shift the next origin absorbs), so a group would carry held parameters and force in
//! weak ones with a strong one; one at a time, the path takes an origin's shift and leaves its
//! turn.
//!
//! Every forward fit reuses one linearisation, `y = H x` about the registration ("before"),
//! whitened once, `A = S H`, `b = S y`: a candidate's fit on a fold is the least-squares
//! solution of the column-scaled normal equations `G_f x = g_f`, `G_f = A_tr^T A_tr`, updated
//! by one row of the Cholesky factor per added column (`L l = G_f[S, j]`,
//! `d^2 = G_f[j, j] - |l|^2`), and its held-out error the quadratic form
//! `SSE_f = y_t^T y_t - 2 x^T H_t^T y_t + x^T H_t^T H_t x`: `O(p^2)` per candidate and fold. A
//! candidate whose column lies in the span of the others on some fold (`d^2` below
//! [`COLLINEAR`] of `G_f[j, j]`) is not taken at that step. Candidates are scored in parallel,
//! each on its own; the best is the lowest score, ties to the earlier parameter, so the path
//! is the same on any number of threads. The selected model is then calibrated by
//! Gauss-Newton as any other.

use super::choice::Front;
pub use super::choice::{
    ChosenFit, Criterion, Fitted, FoldChoices, Nested, SelectionPath, StandInFirst, Step, Trade,
};
use super::kinds::{self, KindData, KindOptions};
use super::prior_scale::{AutoPrior, PriorScale, choose_prior_scale};
use super::{CalibrationError, Held, JointParams, RobotModel, check_folds, standard_errors_of};
use crate::estimation::{LinearEstimate, Residuals, Weights};
use crate::model::ParamOwner;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Folds of `--select cv` unless told.
pub const DEFAULT_FOLDS: usize = 5;

/// A candidate's squared distance to the span of the others, relative to its squared norm,
/// below which it is not added (a sine of 1e-6: the normal equations would lose every digit).
pub const COLLINEAR: f64 = 1e-12;

/// The joint parameters `names`; none when empty.
pub(crate) fn named_joints(names: Vec<String>) -> JointParams {
    if names.is_empty() { JointParams::None } else { JointParams::Named(names) }
}

/// Choose among the joint parameters `options.joints` names by `criterion` (see the
/// [module documentation](self)), for any of the calibrations ([`Front`]): of a marker file,
/// of observation files (distances, contacts, coordinates, cameras' views, markers: the
/// registration is the set-up, the tool point and, with markers, the base and the markers; a
/// fold holds out the observations of its poses, a pair by its first; the CV RMS is of the
/// lengths, mm, angles not scored), of a tree's views (the CV RMS of the views' positions).
/// Then calibrate with [`SelectionPath::options`].
pub fn select<F: Front>(
    front: &F,
    data: &F::Data,
    options: &F::Options,
    criterion: Criterion,
) -> Result<SelectionPath, CalibrationError> {
    F::refuse_select(data)?;
    if let Criterion::Cv { folds } = criterion {
        check_folds(folds, F::poses(data))?;
    }
    match criterion {
        Criterion::T => backward::<F>(|names: Option<&[String]>| match names {
            Some(names) => front.calibrate(data, &front.with_joints(options, names)),
            None => front.calibrate(data, options),
        }),
        _ => front.forward(data, options, criterion),
    }
}

/// The choices made from the data before a calibration: the scale of a preset's priors
/// (`--prior auto`), then the joint parameters (`--select`), with the priors in place.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Choices {
    /// `--prior auto[:PRESET]` or `auto-ml[:PRESET]`: the preset to scale, and the folds to
    /// choose its scale by (unused by the marginal likelihood).
    pub auto_prior: Option<(AutoPrior, usize)>,
    /// `--select`: how to choose the joint parameters.
    pub select: Option<Criterion>,
}

impl Choices {
    /// The choices of the command line's flags: `--prior auto`'s preset, its scale chosen by
    /// `folds`-fold cross-validation ([`DEFAULT_FOLDS`] unless given), and `--select`.
    pub fn from_flags(
        auto_prior: Option<AutoPrior>,
        select: Option<Criterion>,
        folds: Option<usize>,
    ) -> Self {
        let folds = folds.unwrap_or(DEFAULT_FOLDS);
        Self { auto_prior: auto_prior.map(|auto| (auto, folds)), select }
    }
}

/// What [`choose`] chose.
#[derive(Debug, Clone, PartialEq)]
pub struct Chosen<O> {
    /// The options to calibrate with: the scaled priors, the selected parameters.
    pub options: O,
    /// The scale of the preset, and its curve.
    pub scale: Option<PriorScale>,
    /// The selection's path.
    pub path: Option<SelectionPath>,
}

/// Make `choices` on `data`: the preset's scale first ([`choose_prior_scale`]: by
/// cross-validation or the marginal likelihood), then the selection with those priors
/// ([`select`]); the folds of each at most the poses.
pub fn choose<F: Front>(
    front: &F,
    data: &F::Data,
    options: &F::Options,
    choices: &Choices,
) -> Result<Chosen<F::Options>, CalibrationError> {
    let poses = F::poses(data);
    let mut chosen = Chosen { options: options.clone(), scale: None, path: None };
    if let Some((auto, folds)) = &choices.auto_prior {
        let scale = choose_prior_scale(front, data, options, auto, (*folds).min(poses))?;
        chosen.options = F::with_prior(options, |own| auto.chosen(own, &scale));
        chosen.scale = Some(scale);
    }
    if let Some(criterion) = choices.select {
        let criterion = match criterion {
            Criterion::Cv { folds } => Criterion::Cv { folds: folds.min(poses) },
            other => other,
        };
        let path = select(front, data, &chosen.options, criterion)?;
        chosen.options = path.options(front, &chosen.options);
        chosen.path = Some(path);
    }
    Ok(chosen)
}

/// Make `choices` on `data` ([`choose`]) and calibrate with them ([`Front::calibrate`]).
pub fn calibrate_chosen<F: Front>(
    front: &F,
    data: &F::Data,
    options: &F::Options,
    choices: &Choices,
) -> Result<ChosenFit<F::Fit>, CalibrationError> {
    let Chosen { options, scale, path } = choose(front, data, options, choices)?;
    Ok(ChosenFit { scale, path, calibration: front.calibrate(data, &options)? })
}

/// k-fold cross-validation of the choices made from the data, nested: pose `i` is held out in
/// fold `i mod folds`, and on the other folds every choice is made again and the model chosen
/// calibrated ([`calibrate_chosen`]: the preset's scale, the selection, each with folds of its
/// own on them); the held-out poses are scored ([`Front::nested`]: of a marker file before and
/// after, pose by pose, with each fold's choices; of observation files or a tree's views as
/// their `--folds` scores them). Choices made on every pose have seen the held-out ones, so
/// cross-validating only what they chose (with [`Chosen::options`]) is optimistic; this is the figure to expect on new poses.
pub fn cross_validate_choices<F: Front>(
    front: &F,
    data: &F::Data,
    options: &F::Options,
    choices: &Choices,
    folds: usize,
) -> Result<F::Nested, CalibrationError> {
    front.nested(data, options, folds, &|train, options| calibrate_chosen(front, train, options, choices))
}

/// Backward elimination by `|t|` ([`Criterion::T`]), `t = estimate / SE` with the SE of the
/// calibration as it is made (the posterior's where there are priors). A joint's zero or play
/// whose estimate kept parameters can stand in for ([`stand_in`]: one, or a group of up to
/// [`STAND_IN_GROUP`]) is not dropped while one of them has `|t|` below 2 too: the weakest of
/// those goes first (the step says so, [`StandInFirst`]); when every one is strong, the zero goes
/// and the path records the [`Trade`].
fn backward<F: Front>(
    calibrate: impl Fn(Option<&[String]>) -> Result<F::Fit, CalibrationError>,
) -> Result<SelectionPath, CalibrationError> {
    let mut steps = vec![Step { parameter: None, score: f64::NAN, se: f64::NAN, note: None }];
    let (mut current, mut held, mut trades) = (None::<Vec<String>>, None, Vec::new());
    loop {
        let c = calibrate(current.as_deref())?;
        let Fitted { params, values: (before, after), estimate, fixed } = F::fitted(&c);
        let held = held.get_or_insert_with(|| fixed.iter().map(Held::text).collect());
        let params: &crate::model::ParamSet = &params;
        let se = standard_errors_of(params.iter(), estimate);
        let joints: Vec<usize> = (estimate.names.iter())
            .filter_map(|n| params.index_by_name(n))
            .filter(|&i| matches!(params.get(i).owner, ParamOwner::Joint(_)))
            .collect();
        let t = |i: usize| (after[i] - before[i]).abs() / se[i];
        // The smallest |t|, ties to the earlier parameter; a NaN (no standard error) is dropped.
        let weakest = joints.iter().copied().min_by(|&i, &j| by_t(t(i), t(j)));
        let Some(i) = weakest.filter(|&i| is_weak(t(i))) else {
            let selected: Vec<String> = joints.iter().map(|&j| params.get(j).name.clone()).collect();
            let dropped: Vec<String> = (steps.iter().filter_map(|s| s.parameter.clone()))
                .filter(|n| params.index_by_name(n).is_some_and(|i| is_zero_or_play(params.get(i))))
                .collect();
            traded_at_the_end::<F>(&calibrate, &selected, &dropped, &mut trades)?;
            let chosen = steps.len() - 1;
            let held = std::mem::take(held);
            return Ok(SelectionPath { criterion: Criterion::T, steps, chosen, selected, held, trades });
        };
        let covariance = |a: usize, b: usize| estimate_covariance(params, estimate, a, b);
        let (drop, note, trade) = t_drop(params, i, &joints, &covariance, &t);
        trades.extend(trade);
        steps.push(Step {
            parameter: Some(params.get(drop).name.clone()),
            score: t(drop),
            se: f64::NAN,
            note,
        });
        current = Some(joints.iter().filter(|&&j| j != drop).map(|&j| params.get(j).name.clone()).collect());
    }
}

/// Whether a `|t|` is below 2 (or NaN: no standard error).
fn is_weak(t: f64) -> bool {
    t < 2.0 || t.is_nan()
}

/// `|t|` values in the `t` rule's order: smallest first, a NaN before any.
fn by_t(a: f64, b: f64) -> std::cmp::Ordering {
    a.partial_cmp(&b).unwrap_or(if a.is_nan() {
        std::cmp::Ordering::Less
    } else {
        std::cmp::Ordering::Greater
    })
}

/// What the `t` rule drops when `i` (of `kept`) is the weakest, by `|t|` `t`: `i` itself,
/// unless kept parameters stand in for it ([`stand_in`]) and one of them is weak too, then the
/// weakest of those, with why; with strong stand-ins `i`, and the trade.
fn t_drop(
    params: &crate::model::ParamSet,
    i: usize,
    kept: &[usize],
    covariance: &dyn Fn(usize, usize) -> f64,
    t: &dyn Fn(usize) -> f64,
) -> (usize, Option<StandInFirst>, Option<Trade>) {
    let Some(group) = stand_in(params, i, kept, covariance) else { return (i, None, None) };
    let name = |k: usize| params.get(k).name.clone();
    let weak = group.members.iter().copied().filter(|&k| is_weak(t(k))).min_by(|&a, &b| by_t(t(a), t(b)));
    match weak {
        Some(k) => {
            let with = group.members.iter().filter(|&&m| m != k).map(|&m| name(m)).collect();
            (k, Some(StandInFirst { stands_in_for: name(i), with, correlation: group.correlation }), None)
        }
        None => (i, None, Some(t_trade(params, i, &group, t))),
    }
}

/// The trade of the `t` rule leaving `i` out while `group` stands in for it, with their `|t|`.
fn t_trade(params: &crate::model::ParamSet, i: usize, group: &StandIn, t: &dyn Fn(usize) -> f64) -> Trade {
    Trade {
        parameter: params.get(i).name.clone(),
        t: Some(t(i)),
        stand_ins: group.members.iter().map(|&k| params.get(k).name.clone()).collect(),
        stand_in_t: group.members.iter().map(|&k| t(k)).collect(),
        correlation: group.correlation,
    }
}

/// The trades of the `t` rule's last model `selected`, checked at its end: the path judged
/// each stand-in against the model of its step, and later steps change what stands in. Each
/// joint's zero or play it dropped (`dropped`) and did not trade as it went is calibrated back
/// into the last model: where chosen parameters stand in for it there ([`stand_in`]), the trade
/// (its `|t|` and theirs of that fit).
fn traded_at_the_end<F: Front>(
    calibrate: &impl Fn(Option<&[String]>) -> Result<F::Fit, CalibrationError>,
    selected: &[String],
    dropped: &[String],
    trades: &mut Vec<Trade>,
) -> Result<(), CalibrationError> {
    for zero in dropped {
        if trades.iter().any(|t| &t.parameter == zero) {
            continue;
        }
        let names: Vec<String> = selected.iter().cloned().chain([zero.clone()]).collect();
        let c = calibrate(Some(&names))?;
        let Fitted { params, values: (before, after), estimate, .. } = F::fitted(&c);
        let params: &crate::model::ParamSet = &params;
        let Some(i) = params.index_by_name(zero) else { continue };
        let se = standard_errors_of(params.iter(), estimate);
        let t = |k: usize| (after[k] - before[k]).abs() / se[k];
        let kept: Vec<usize> = selected.iter().filter_map(|n| params.index_by_name(n)).collect();
        let covariance = |a: usize, b: usize| estimate_covariance(params, estimate, a, b);
        if let Some(group) = stand_in(params, i, &kept, &covariance) {
            trades.push(t_trade(params, i, &group, &t));
        }
    }
    Ok(())
}

/// The correlation above which parameters' estimates stand in for a joint's zero or play:
/// the poses (and priors) barely tell the zero from them. Of a group, the multiple correlation.
pub const STANDS_IN: f64 = 0.9;

/// The most parameters that stand in together for a joint's zero or play: its error may be
/// carried by a few (a length and a twist of the next joint), never by the model at large.
pub const STAND_IN_GROUP: usize = 3;

/// Groups of two or more are drawn from this many of the kept parameters, those most
/// correlated with the zero or play (the work stays `O(POOL^3)` per zero on any model).
const GROUP_POOL: usize = 24;

/// Relative slack of the comparison with [`STANDS_IN`]: a group's multiple correlation is
/// found by a small solve whose rounding must not decide a case at the threshold itself.
const STAND_IN_SLACK: f64 = 1e-9;

/// Whether `p` is a joint's zero (its offset) or its play: kept before what can only stand in
/// for it.
fn is_zero_or_play(p: &crate::model::ParamInfo) -> bool {
    matches!(p.owner, ParamOwner::Joint(_)) && (p.is_offset || p.kind == crate::model::ParamKind::Play)
}

/// Kept parameters that stand in for a joint's zero or play ([`stand_in`]).
#[derive(Debug, Clone, PartialEq)]
struct StandIn {
    /// The parameters (full-vector indices), in the order of `kept`.
    members: Vec<usize>,
    /// Signed for one, the multiple correlation of a group.
    correlation: f64,
}

/// The parameters among `kept` (full-vector indices) that stand in for `i`, a joint's zero or
/// play, by their estimates' covariance (`covariance(a, b)` of the estimates, or of the inverse
/// normal equations): the smallest group (one parameter, then two, up to [`STAND_IN_GROUP`]),
/// none of them itself a zero or a play, whose (multiple) correlation with `i` is at least
/// [`STANDS_IN`] in magnitude, the most correlated of that size. A group is minimal: no part of
/// it stands in alone. `None` for any other `i`, or where nothing does.
fn stand_in(
    params: &crate::model::ParamSet,
    i: usize,
    kept: &[usize],
    covariance: &dyn Fn(usize, usize) -> f64,
) -> Option<StandIn> {
    if !is_zero_or_play(params.get(i))
        || covariance(i, i).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
    {
        return None;
    }
    let mut others: Vec<usize> = (kept.iter().copied())
        .filter(|&k| k != i && !is_zero_or_play(params.get(k)) && covariance(k, k) > 0.0)
        .collect();
    // The correlations among `i` (first) and the others, once.
    let all: Vec<usize> = std::iter::once(i).chain(others.iter().copied()).collect();
    let r = DMatrix::from_fn(all.len(), all.len(), |a, b| {
        covariance(all[a], all[b]) / (covariance(all[a], all[a]) * covariance(all[b], all[b])).sqrt()
    });
    let position = |k: usize| all.iter().position(|&a| a == k).expect("kept");
    let stands = |c: f64| c.abs() >= STANDS_IN * (1.0 - STAND_IN_SLACK);
    let best = |groups: Vec<Vec<usize>>| -> Option<StandIn> {
        (groups.into_iter())
            .filter_map(|g| {
                let at: Vec<usize> = g.iter().map(|&k| position(k)).collect();
                multiple_correlation(&r, &at).map(|c| StandIn { members: g, correlation: c })
            })
            .filter(|s| stands(s.correlation))
            .max_by(|a, b| a.correlation.abs().total_cmp(&b.correlation.abs()))
    };
    if let Some(one) = best(others.iter().map(|&k| vec![k]).collect()) {
        return Some(one);
    }
    // Groups from the most correlated others, each group in the order of `kept`.
    others.sort_by(|&a, &b| r[(0, position(b))].abs().total_cmp(&r[(0, position(a))].abs()));
    others.truncate(GROUP_POOL);
    let order = |mut g: Vec<usize>| {
        g.sort_by_key(|k| kept.iter().position(|x| x == k));
        g
    };
    (2..=STAND_IN_GROUP).find_map(|size| best(subsets(&others, size).into_iter().map(order).collect()))
}

/// Every subset of `size` of `items`, in lexicographic order of positions.
fn subsets(items: &[usize], size: usize) -> Vec<Vec<usize>> {
    if size == 0 {
        return vec![Vec::new()];
    }
    (0..items.len())
        .flat_map(|first| {
            subsets(&items[first + 1..], size - 1).into_iter().map(move |mut rest| {
                rest.insert(0, items[first]);
                rest
            })
        })
        .collect()
}

/// The correlation of the estimate of the first row of the correlation matrix `r` with the
/// group `at` (positions in `r`): the signed correlation for one, for more the multiple
/// correlation `sqrt(r_0G^T R_GG^-1 r_G0)`; `None` where the group's own correlations are
/// singular (one of them the others' combination: a smaller group says as much).
fn multiple_correlation(r: &DMatrix<f64>, at: &[usize]) -> Option<f64> {
    if let [k] = at {
        return Some(r[(0, *k)]).filter(|c| c.is_finite());
    }
    let inner = DMatrix::from_fn(at.len(), at.len(), |a, b| r[(at[a], at[b])]);
    let cross = DVector::from_fn(at.len(), |a, _| r[(0, at[a])]);
    let solved = inner.cholesky()?.solve(&cross);
    let r2 = cross.dot(&solved);
    (r2.is_finite()).then(|| r2.clamp(0.0, 1.0).sqrt())
}

/// The covariance in `estimate` of parameters `a` and `b` (indices of `params`).
fn estimate_covariance(
    params: &crate::model::ParamSet,
    estimate: &LinearEstimate,
    a: usize,
    b: usize,
) -> f64 {
    let column = |i: usize| estimate.names.iter().position(|n| *n == params.get(i).name);
    match (column(a), column(b)) {
        (Some(a), Some(b)) => estimate.covariance[(a, b)],
        _ => f64::NAN,
    }
}

/// The calibration linearised once about the registration ("before"), for the parameters
/// asked for that the poses identify: whitened by the estimator (`A = S H`, `b = S y`) to fit,
/// unweighted (`H`, `y`) to score, both column-scaled alike.
pub(crate) struct LinearModel {
    params: crate::model::ParamSet,
    /// Each column's parameter (an index of `params`); `None` for a set-up parameter.
    columns: Vec<Option<usize>>,
    /// Each column's name.
    names: Vec<String>,
    /// The held ones, in words.
    held: Vec<String>,
    whitened: Scaled,
    unweighted: Scaled,
    /// Each data row's pose: its fold is the pose's.
    pose_of_row: Vec<usize>,
    /// Each data row's share of one scored error: a third of a marker for its coordinates, one
    /// for a length observation, none for an angle (whose unweighted row is zero).
    share: Vec<f64>,
}

/// A linear model's system about the registration: [`LinearModel::new`]'s parts.
pub(crate) struct LinearParts {
    /// `A = S H` and `b = S y` of the identified columns, the prior's rows below them.
    pub whitened: (DMatrix<f64>, DVector<f64>),
    /// `H` and `y`, unweighted, the rows that are not scored zero.
    pub unweighted: (DMatrix<f64>, DVector<f64>),
    /// Each data row's pose, and its share of one scored error.
    pub rows: Vec<(usize, f64)>,
}

impl LinearParts {
    /// The parts of `problem` linearised at `x` (its columns those the gauge keeps): `H` and
    /// `y` unweighted, the rows of `rows` that score nothing (share 0) zeroed, and whitened by
    /// `weights` with the `prior`'s rows below them.
    pub(crate) fn of_problem(
        problem: &impl Residuals,
        (x, weights, prior): (&DVector<f64>, &Weights, Option<crate::estimation::PriorRows>),
        rows: Vec<(usize, f64)>,
    ) -> Self {
        let mut h = DMatrix::zeros(problem.equations(), problem.parameters());
        let mut y = problem.evaluate(x, Some(&mut h));
        // The whitened system, held whole: the path fits it fold by fold.
        let (mut a, mut b) = (h.clone(), y.clone());
        weights.apply(&mut a);
        weights.apply(&mut b);
        let whitened = match prior {
            Some(prior) => prior.augment(&a, &b, x),
            None => (a, b),
        };
        for (r, _) in rows.iter().enumerate().filter(|(_, (_, share))| *share == 0.0) {
            h.row_mut(r).fill(0.0);
            y[r] = 0.0;
        }
        Self { whitened, unweighted: (h, y), rows }
    }
}

impl LinearModel {
    /// The model of the columns `columns` (named `names`) of `params`, the held in `held`,
    /// from `parts`; the columns scaled by the whitened system's column norms.
    pub(crate) fn new(
        params: &crate::model::ParamSet,
        (columns, names): (Vec<Option<usize>>, Vec<String>),
        held: Vec<String>,
        parts: LinearParts,
    ) -> Self {
        let LinearParts { whitened: (a, b), unweighted: (h, y), rows } = parts;
        let data = rows.len();
        let scale: Vec<f64> = (a.rows(0, data).column_iter())
            .map(|c| c.norm())
            .map(|n| if n > 0.0 { 1.0 / n } else { 1.0 })
            .collect();
        let (pose_of_row, share): (Vec<usize>, Vec<f64>) = rows.into_iter().unzip();
        Self {
            params: params.clone(),
            columns,
            names,
            held,
            whitened: Scaled::new(&a, &b, &scale),
            unweighted: Scaled::new(&h, &y, &scale),
            pose_of_row: dense(&pose_of_row),
            share,
        }
    }

    /// The "before" fit of `data` (the set-up, the tool point; with markers the base and the
    /// markers; with coordinates and no markers the calibration of no joint parameter, which
    /// places the base: [`kinds::start_registered`]), then the gauge of `options`' parameters and
    /// the system about it. Its rows are
    /// the observations, each in the fold of its pose (a pair by its first), each counting its
    /// [`Observation::error_share`](kinds::Observation::error_share) of an error: a marker's
    /// position one, an angle none (its unweighted row is zero: the CV RMS is of lengths, mm).
    pub(crate) fn of_kinds(
        model: &RobotModel,
        data: &KindData,
        options: &KindOptions,
    ) -> Result<Self, CalibrationError> {
        let (_, prepared) = kinds::prepare(model, data, options)?;
        let started = kinds::start_registered(model, &prepared, data, options)?;
        let rows: Vec<(usize, f64)> = data.observations.iter().map(|o| (o.pose(), o.error_share())).collect();
        let fixed = started.gauged.fixed.clone();
        Ok(Self::of_started(&prepared, &started, rows, fixed))
    }

    /// The model of what `prepared` asks for, `started` (linearised about its "before" fit,
    /// the columns its gauge keeps): `rows` each row's pose (its fold) and its share of one
    /// scored error; `fixed` what the gauge held, in words.
    pub(super) fn of_started(
        prepared: &kinds::Prepared,
        started: &kinds::Started<'_>,
        rows: Vec<(usize, f64)>,
        fixed: Vec<Held>,
    ) -> Self {
        let kinds::Gauged { identifiable, prior, .. } = &started.gauged;
        let (kept, kept_setup) = prepared.kept(identifiable);
        let (before, before_setup) = (started.before.clone(), started.before_setup.clone());
        let problem = started.base.reselect(&kept, before, before_setup, kept_setup);
        let start = started.linearised.select(identifiable);
        let prior = prior.as_ref().map(|p| p.select(identifiable));
        let parts = LinearParts::of_problem(&problem, (&start.x, &started.weights, prior), rows);
        // The robot's kept parameters, then the set-up's.
        let columns = (0..problem.parameters()).map(|c| kept.indices().get(c).copied()).collect();
        let held = prepared.every_held(fixed).iter().map(Held::text).collect();
        Self::new(&prepared.params, (columns, problem.names()), held, parts)
    }

    /// The trades of the model of the registration and the `chosen` columns: each candidate
    /// joint zero or play left out for which chosen parameters stand in ([`stand_in`]), from
    /// the inverse normal equations on every pose (priors in place) with it added.
    fn trades(&self, chosen: &[usize]) -> Vec<Trade> {
        let all = Fit::new(&self.whitened, None);
        let registration = (0..self.columns.len()).filter(|&c| self.is_registration(c));
        let model: Vec<usize> = registration.chain(chosen.iter().copied()).collect();
        let index = |c: usize| self.columns[c];
        let zero_or_play = |c: usize| index(c).is_some_and(|i| is_zero_or_play(self.params.get(i)));
        let kept: Vec<usize> = chosen.iter().filter_map(|&c| index(c)).collect();
        let mut out = Vec::new();
        for o in (0..self.columns.len()).filter(|&c| !model.contains(&c) && zero_or_play(c)) {
            let columns: Vec<usize> = model.iter().copied().chain([o]).collect();
            let gram =
                DMatrix::from_fn(columns.len(), columns.len(), |a, b| all.gram[(columns[a], columns[b])]);
            let Some(inverse) = gram.cholesky().map(|c| c.inverse()) else { continue };
            let at = |i: usize| columns.iter().position(|&c| index(c) == Some(i)).expect("a column");
            let covariance = |a: usize, b: usize| inverse[(at(a), at(b))];
            let Some(o) = index(o) else { continue };
            if let Some(group) = stand_in(&self.params, o, &kept, &covariance) {
                out.push(Trade {
                    parameter: self.params.get(o).name.clone(),
                    t: None,
                    stand_ins: group.members.iter().map(|&k| self.params.get(k).name.clone()).collect(),
                    stand_in_t: Vec::new(),
                    correlation: group.correlation,
                });
            }
        }
        out
    }

    /// Whether column `c` is the registration's (the base's, a marker's, the tool's, the
    /// set-up's): always in the model.
    fn is_registration(&self, c: usize) -> bool {
        self.columns[c].is_none_or(|i| !matches!(self.params.get(i).owner, ParamOwner::Joint(_)))
    }

    /// The forward path by `criterion` ([`Criterion::Cv`], [`Criterion::Bic`]) and the model
    /// it chooses.
    pub(crate) fn forward(self, criterion: Criterion) -> SelectionPath {
        let mut fits = self.fits(criterion);
        let (steps, order) = walk(&mut fits, &self, criterion);
        let chosen = choose_step(&steps, criterion);
        let mut columns: Vec<usize> = order[..chosen].to_vec();
        columns.sort_unstable();
        let selected = columns.iter().map(|&c| self.names[c].clone()).collect();
        let trades = self.trades(&order[..chosen]);
        SelectionPath { criterion, steps, chosen, selected, held: self.held, trades }
    }

    /// The fits a criterion compares, the registration's columns in: one per fold for CV (pose
    /// `k` held out in fold `k mod F`, `k` its number among the poses that have rows, [`dense`];
    /// `F` at most their number), one on every pose for BIC.
    fn fits(&self, criterion: Criterion) -> Vec<Fit> {
        // No empty fold: at most one per pose.
        let poses = self.pose_of_row.iter().max().map_or(1, |p| p + 1);
        let mut fits: Vec<Fit> = match criterion {
            Criterion::Cv { folds } => {
                let folds = folds.min(poses);
                (0..folds)
                    .map(|f| {
                        let rows: Vec<usize> = (0..self.pose_of_row.len())
                            .filter(|&r| self.pose_of_row[r] % folds == f)
                            .collect();
                        let count = rows.iter().map(|&r| self.share[r]).sum();
                        Fit::new(&self.whitened, Some((&self.unweighted, &rows, count)))
                    })
                    .collect()
            }
            _ => vec![Fit::new(&self.whitened, None)],
        };
        for c in (0..self.columns.len()).filter(|&c| self.is_registration(c)) {
            for fit in &mut fits {
                if let Some(trial) = fit.trial(c) {
                    fit.accept(c, trial);
                }
            }
        }
        fits
    }
}

/// Each row's pose numbered among the poses that have rows (`0..n`, in order): a fold's
/// training rows keep the data's pose numbers, some with no rows left, and pose `p` goes to
/// fold `p mod F` by its number here, so that no fold is empty.
fn dense(pose_of_row: &[usize]) -> Vec<usize> {
    let mut poses = pose_of_row.to_vec();
    poses.sort_unstable();
    poses.dedup();
    pose_of_row.iter().map(|p| poses.binary_search(p).expect("a pose of the rows")).collect()
}

/// The forward path from `fits`: at each step the candidate of `linear` whose trial scores
/// lowest (scored in parallel, ties to the earlier column), until none is left that every fit
/// can take. The steps, and the columns in the order added.
fn walk(fits: &mut [Fit], linear: &LinearModel, criterion: Criterion) -> (Vec<Step>, Vec<usize>) {
    // The data's equations (the prior's rows are not observations).
    let equations = linear.pose_of_row.len();
    let now: Vec<Trial> = fits.iter().map(Fit::current).collect();
    let (first, first_se) = score(fits, &now, criterion, equations);
    let mut steps = vec![Step { parameter: None, score: first, se: first_se, note: None }];
    let mut order = Vec::new();
    let mut left: Vec<usize> = (0..linear.columns.len()).filter(|&c| !linear.is_registration(c)).collect();
    while !left.is_empty() {
        let scored: Vec<Option<Scored>> = left
            .par_iter()
            .map(|&j| {
                let trials = fits.iter().map(|f| f.trial(j)).collect::<Option<Vec<Trial>>>()?;
                Some((score(fits, &trials, criterion, equations), trials))
            })
            .collect();
        let best = (0..left.len())
            .filter_map(|i| scored[i].as_ref().map(|s| (i, s.0.0)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = best else { break };
        let j = left.remove(i);
        let ((value, se), trials) = scored.into_iter().nth(i).flatten().expect("scored");
        for (fit, trial) in fits.iter_mut().zip(trials) {
            fit.accept(j, trial);
        }
        order.push(j);
        let name = linear.names[j].clone();
        steps.push(Step { parameter: Some(name), score: value, se, note: None });
    }
    (steps, order)
}

/// A candidate scored: its (score, SE), and its trial on every fit.
type Scored = ((f64, f64), Vec<Trial>);

/// The score of `fits` each with its `trials` (a column added, or [`Fit::current`]): the CV
/// RMS and its SE, or the BIC (and NaN) of the fit on every pose.
fn score(fits: &[Fit], trials: &[Trial], criterion: Criterion, equations: usize) -> (f64, f64) {
    match criterion {
        Criterion::Cv { .. } => cv_rms(fits.iter().zip(trials).map(|(f, t)| (t.sse_test, f.count()))),
        _ => (bic(trials[0].rss, trials[0].parameters, equations), f64::NAN),
    }
}

/// `BIC = N ln(RSS / N) + p ln N` of a least-squares fit of `p` parameters to `N` equations
/// whose noise scale is estimated with them (Schwarz 1978).
fn bic(rss: f64, parameters: usize, equations: usize) -> f64 {
    let n = equations as f64;
    n * (rss.max(f64::MIN_POSITIVE) / n).ln() + parameters as f64 * n.ln()
}

/// The step a criterion chooses: for CV the first whose score is within one standard error of
/// the lowest score's (the one-standard-error rule), otherwise the lowest.
fn choose_step(steps: &[Step], criterion: Criterion) -> usize {
    let best = (0..steps.len()).min_by(|&a, &b| steps[a].score.total_cmp(&steps[b].score)).unwrap_or(0);
    match criterion {
        Criterion::Cv { .. } => {
            let within = steps[best].score + steps[best].se;
            (0..=best).find(|&k| steps[k].score <= within).unwrap_or(best)
        }
        _ => best,
    }
}

/// The CV RMS and its standard error from each fold's held-out `(SSE, errors)` (markers, or
/// length observations).
fn cv_rms(folds: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    let folds: Vec<(f64, f64)> = folds.collect();
    let (sse, n): (f64, f64) = folds.iter().fold((0.0, 0.0), |(s, n), &(f, c)| (s + f, n + c));
    let rms: Vec<f64> = folds.iter().map(|&(s, c)| (s.max(0.0) / c.max(1.0)).sqrt()).collect();
    let k = rms.len() as f64;
    let mean = rms.iter().sum::<f64>() / k;
    let sd = (rms.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0)).sqrt();
    ((sse.max(0.0) / n.max(1.0)).sqrt(), sd / k.sqrt())
}

/// A linear system with its columns scaled (`A D`, `b`), rows as the stacked system's.
struct Scaled {
    a: DMatrix<f64>,
    b: DVector<f64>,
}

impl Scaled {
    /// `a D`, `b`, with `D = diag(scale)`.
    fn new(a: &DMatrix<f64>, b: &DVector<f64>, scale: &[f64]) -> Self {
        let mut a = a.clone();
        for (mut column, s) in a.column_iter_mut().zip(scale) {
            column *= *s;
        }
        Self { a, b: b.clone() }
    }

    /// `A_R^T A_R`, `A_R^T b_R` and `b_R^T b_R` of the rows `R`.
    fn normal(&self, rows: &[usize]) -> (DMatrix<f64>, DVector<f64>, f64) {
        let a = self.a.select_rows(rows);
        let b = self.b.select_rows(rows);
        (a.tr_mul(&a), a.tr_mul(&b), b.norm_squared())
    }
}

/// One fold's fit of a growing set of columns: the training normal equations `G x = g`
/// factored by Cholesky one column at a time, and the held-out fold's quadratic form.
struct Fit {
    gram: DMatrix<f64>,
    rhs: DVector<f64>,
    bb: f64,
    test: Option<(DMatrix<f64>, DVector<f64>, f64, f64)>,
    /// The columns in, in the order added.
    members: Vec<usize>,
    /// The Cholesky factor of `gram[members, members]` (rows and columns in `members` order).
    l: DMatrix<f64>,
    /// `L^-1 g[members]`.
    z: Vec<f64>,
}

/// A candidate column tried on one fit: its row of the Cholesky factor, and the fit's errors
/// with it.
struct Trial {
    l: Vec<f64>,
    d: f64,
    z: f64,
    /// The columns of the fit with it.
    parameters: usize,
    /// The whitened training cost.
    rss: f64,
    /// The unweighted held-out `|y_t - H_t x|^2` (0 without a held-out fold).
    sse_test: f64,
}

impl Fit {
    /// The fit of no columns on every row of `whitened` but the held-out `test` ones
    /// (`(unweighted system, its rows, the errors they score)`), or on every row without a test.
    fn new(whitened: &Scaled, test: Option<(&Scaled, &[usize], f64)>) -> Self {
        let p = whitened.a.ncols();
        let (mut gram, mut rhs, mut bb) = whitened.normal(&(0..whitened.b.len()).collect::<Vec<_>>());
        let test = test.map(|(unweighted, rows, count)| {
            let (g_t, r_t, b_t) = whitened.normal(rows);
            gram -= g_t;
            rhs -= r_t;
            bb -= b_t;
            let (q, c, s) = unweighted.normal(rows);
            (q, c, s, count)
        });
        Self { gram, rhs, bb, test, members: Vec::new(), l: DMatrix::zeros(p, p), z: Vec::new() }
    }

    /// Errors held out (markers, or length observations).
    fn count(&self) -> f64 {
        self.test.as_ref().map_or(0.0, |t| t.3)
    }

    /// The whitened training cost of the current columns, `b^T b - |z|^2`.
    fn rss(&self) -> f64 {
        self.bb - self.z.iter().map(|z| z * z).sum::<f64>()
    }

    /// The current fit as a trial of no column (its held-out error).
    fn current(&self) -> Trial {
        let x = self.solve(None);
        let (parameters, rss) = (self.members.len(), self.rss());
        Trial { l: Vec::new(), d: 0.0, z: 0.0, parameters, rss, sse_test: self.sse_test(None, &x) }
    }

    /// Column `j` added: `None` if it lies in the span of the current columns on this fold.
    fn trial(&self, j: usize) -> Option<Trial> {
        let s = self.members.len();
        let mut l = vec![0.0; s];
        for r in 0..s {
            let dot: f64 = (0..r).map(|c| self.l[(r, c)] * l[c]).sum();
            l[r] = (self.gram[(self.members[r], j)] - dot) / self.l[(r, r)];
        }
        let d2 = self.gram[(j, j)] - l.iter().map(|v| v * v).sum::<f64>();
        if d2.is_nan() || d2 <= COLLINEAR * self.gram[(j, j)] {
            return None;
        }
        let d = d2.sqrt();
        let z = (self.rhs[j] - l.iter().zip(&self.z).map(|(a, b)| a * b).sum::<f64>()) / d;
        let rss = self.rss() - z * z;
        let mut trial = Trial { l, d, z, parameters: s + 1, rss, sse_test: 0.0 };
        if self.test.is_some() {
            let x = self.solve(Some(&trial));
            trial.sse_test = self.sse_test(Some(j), &x);
        }
        Some(trial)
    }

    /// Add column `j` as `trial` found it.
    fn accept(&mut self, j: usize, trial: Trial) {
        let s = self.members.len();
        for (c, v) in trial.l.iter().enumerate() {
            self.l[(s, c)] = *v;
        }
        self.l[(s, s)] = trial.d;
        self.z.push(trial.z);
        self.members.push(j);
    }

    /// The (scaled) estimate of the current columns, with `trial`'s last if given:
    /// `L^T x = z` by back substitution.
    fn solve(&self, trial: Option<&Trial>) -> Vec<f64> {
        let s = self.members.len();
        let n = s + usize::from(trial.is_some());
        let entry = |r: usize, c: usize| match trial {
            Some(t) if r == s => {
                if c == s {
                    t.d
                } else {
                    t.l[c]
                }
            }
            _ => self.l[(r, c)],
        };
        let z = |r: usize| if r == s { trial.map_or(0.0, |t| t.z) } else { self.z[r] };
        let mut x = vec![0.0; n];
        for r in (0..n).rev() {
            let dot: f64 = (r + 1..n).map(|c| entry(c, r) * x[c]).sum();
            x[r] = (z(r) - dot) / entry(r, r);
        }
        x
    }

    /// The held-out fold's unweighted `|y_t - H_t x|^2 = y_t^T y_t - 2 x^T H_t^T y_t +
    /// x^T H_t^T H_t x` for `x` on the current columns, and column `extra` last if given.
    fn sse_test(&self, extra: Option<usize>, x: &[f64]) -> f64 {
        let Some((q, c, s, _)) = &self.test else { return 0.0 };
        let column =
            |a: usize| if a < self.members.len() { self.members[a] } else { extra.expect("one more") };
        let mut quadratic = 0.0;
        let mut linear = 0.0;
        for (a, xa) in x.iter().enumerate() {
            let i = column(a);
            linear += xa * c[i];
            quadratic += xa * x.iter().enumerate().map(|(b, xb)| q[(i, column(b))] * xb).sum::<f64>();
        }
        s - 2.0 * linear + quadratic
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fold's training rows keep the data's pose numbers (here the poses of an outer 3-fold
    /// split, fold 0 held out: 1, 2, 4, 5, 7, 8, 10, 11): numbered among themselves, every
    /// inner fold of 3 holds poses out (3, 3 and 2; by their own numbers, `p mod 3`, one fold
    /// would hold none); with more folds than poses, one pose each.
    #[test]
    fn inner_folds_are_never_empty() {
        let poses: Vec<usize> = (0..12).filter(|p| p % 3 != 0).collect();
        assert_eq!(dense(&[4, 4, 1, 7]), [1, 1, 0, 2]);
        let rows: Vec<(usize, f64)> = poses.iter().flat_map(|&p| [(p, 1.0 / 3.0); 3]).collect();
        let value =
            |i: usize, j: usize| ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0 + f64::from(u8::from(i == j));
        let (a, y) =
            (DMatrix::from_fn(rows.len(), 2, value), DVector::from_fn(rows.len(), |i, _| value(i, 5)));
        let params = crate::model::ParamSet::new(&RobotModel::preset("puma560").unwrap());
        let parts = LinearParts { whitened: (a.clone(), y.clone()), unweighted: (a, y), rows };
        let linear =
            LinearModel::new(&params, (vec![None, Some(0)], vec!["s".into(), "j".into()]), Vec::new(), parts);
        for (folds, expected) in [(3, vec![3.0, 3.0, 2.0]), (20, vec![1.0; 8])] {
            let held: Vec<f64> = (linear.fits(Criterion::Cv { folds }).iter())
                .map(|fit| fit.test.as_ref().map(|t| t.3.round()).expect("a held-out part"))
                .collect();
            assert_eq!(held, expected, "{folds} folds: the errors each holds out");
        }
    }

    /// The incremental fit (Cholesky row by row, the held-out error as a quadratic form) gives
    /// the direct least-squares answer of every growing subset: training cost, held-out error,
    /// and a collinear column refused.
    #[test]
    fn incremental_fits_are_the_direct_least_squares_ones() {
        let (m, p) = (60, 6);
        let value =
            |i: usize, j: usize| ((i as f64 * 12.9898 + j as f64 * 78.233).sin() * 43758.5453).fract();
        let mut a = DMatrix::from_fn(m, p, value);
        // Column 5 is a combination of columns 0 and 1.
        let dependent = a.column(0) * 2.0 - a.column(1);
        a.set_column(5, &dependent);
        let b = DVector::from_fn(m, |i, _| value(i, 9));
        let h = DMatrix::from_fn(m, p, |i, j| 2.0 * value(i, j) + 0.01 * (i + j) as f64);
        let y = DVector::from_fn(m, |i, _| value(i, 11));
        let scale = vec![1.0; p];
        let (whitened, unweighted) = (Scaled::new(&a, &b, &scale), Scaled::new(&h, &y, &scale));
        let test: Vec<usize> = (0..m).filter(|i| i % 4 == 1).collect();
        let train: Vec<usize> = (0..m).filter(|i| i % 4 != 1).collect();
        let mut fit = Fit::new(&whitened, Some((&unweighted, &test, test.len() as f64)));
        let mut members = Vec::new();
        for j in [3, 0, 1, 4] {
            let trial = fit.trial(j).expect("independent");
            members.push(j);
            let a_tr = a.select_rows(&train).select_columns(&members);
            let x = a_tr.clone().svd(true, true).solve(&b.select_rows(&train), 1e-14).unwrap();
            let rss = (b.select_rows(&train) - &a_tr * &x).norm_squared();
            let sse =
                (y.select_rows(&test) - h.select_rows(&test).select_columns(&members) * &x).norm_squared();
            assert!((trial.rss - rss).abs() < 1e-10 * rss, "{} {rss}", trial.rss);
            assert!((trial.sse_test - sse).abs() < 1e-10 * sse, "{} {sse}", trial.sse_test);
            fit.accept(j, trial);
        }
        assert!(fit.trial(5).is_none(), "column 5 lies in the span of 0 and 1");
        assert!(fit.trial(2).is_some());
    }

    /// A joint's zero or play has a stand-in: the kept parameter, not itself a zero or a play,
    /// whose estimate is the most correlated with its own, at 0.9 or more in magnitude; any other
    /// parameter has none.
    #[test]
    fn a_stand_in_is_the_most_correlated_other_kind_of_parameter() {
        let model = RobotModel::preset("puma560").unwrap();
        let params = model.params();
        let at = |name: &str| params.index_by_name(name).unwrap();
        let (zero, length, twist, other_zero) = (at("j2.theta"), at("j2.a"), at("j3.alpha"), at("j3.theta"));
        // Unit variances; correlations: zero-length -0.95, zero-twist 0.92, zero-other zero 0.99.
        let correlation = |a: usize, b: usize| -> f64 {
            let pair = |x: usize, y: usize| (a == x && b == y) || (a == y && b == x);
            if a == b {
                1.0
            } else if pair(zero, length) {
                -0.95
            } else if pair(zero, twist) {
                0.92
            } else if pair(zero, other_zero) {
                0.99
            } else {
                0.0
            }
        };
        let kept = [length, twist, other_zero];
        let one = |k: usize, c: f64| Some(StandIn { members: vec![k], correlation: c });
        assert_eq!(stand_in(&params, zero, &kept, &correlation), one(length, -0.95));
        assert_eq!(stand_in(&params, zero, &[twist, other_zero], &correlation), one(twist, 0.92));
        assert_eq!(stand_in(&params, zero, &[other_zero], &correlation), None, "another zero is no stand-in");
        assert_eq!(
            stand_in(&params, length, &[zero, twist], &correlation),
            None,
            "only a zero or a play has one"
        );
        // Halved, no one parameter reaches 0.9; the length and the twist together (uncorrelated
        // with each other here) reach sqrt(0.475^2 + 0.46^2) = 0.66: still none.
        let weak = |a: usize, b: usize| correlation(a, b) * if a == b { 1.0 } else { 0.5 };
        assert_eq!(stand_in(&params, zero, &kept, &weak), None, "below 0.9");
    }

    /// A group stands in where no one parameter does: a zero correlated by 0.7 with a length
    /// and by -0.65 with a twist, the two uncorrelated, has the multiple correlation
    /// `sqrt(0.7^2 + 0.65^2) = 0.955` with them; a third parameter correlated by 0.3 with the
    /// zero does not join (the pair is the smallest group). A group whose own correlations are
    /// singular is no group; with groups of one allowed, one strong parameter is taken first.
    #[test]
    fn a_group_stands_in_where_no_one_parameter_does() {
        let model = RobotModel::preset("puma560").unwrap();
        let params = model.params();
        let at = |name: &str| params.index_by_name(name).unwrap();
        let (zero, length, twist, third) = (at("j2.theta"), at("j2.a"), at("j3.alpha"), at("j4.d"));
        let correlation = |a: usize, b: usize| -> f64 {
            let pair = |x: usize, y: usize| (a == x && b == y) || (a == y && b == x);
            match () {
                _ if a == b => 4.0,
                _ if pair(zero, length) => 0.7 * 4.0,
                _ if pair(zero, twist) => -0.65 * 4.0,
                _ if pair(zero, third) => 0.3 * 4.0,
                _ => 0.0,
            }
        };
        let found = stand_in(&params, zero, &[third, twist, length], &correlation).expect("a group");
        assert_eq!(found.members, [twist, length], "in the order kept");
        let expected = (0.7f64.powi(2) + 0.65f64.powi(2)).sqrt();
        assert!((found.correlation - expected).abs() < 1e-12, "{}", found.correlation);
        assert_eq!(stand_in(&params, zero, &[third, length], &correlation), None, "0.76 with the pair");
        // A group at the threshold itself, to rounding: it stands in.
        let at_threshold = |a: usize, b: usize| {
            let c = correlation(a, b);
            if c.abs() == 0.65 * 4.0 { -(0.81f64 - 0.49).sqrt() * 4.0 } else { c }
        };
        let found = stand_in(&params, zero, &[twist, length], &at_threshold).expect("at 0.9");
        assert!((found.correlation - STANDS_IN).abs() < 1e-12, "{}", found.correlation);
        assert_eq!(subsets(&[1, 2, 3], 2), [vec![1, 2], vec![1, 3], vec![2, 3]]);
    }

    /// The CV RMS pools the folds' squared errors; its standard error is the spread of the
    /// folds' RMS over the square root of their number.
    #[test]
    fn cv_rms_pools_the_folds() {
        let (rms, se) = cv_rms([(4.0, 1.0), (16.0, 1.0)].into_iter());
        assert!((rms - 10f64.sqrt()).abs() < 1e-15);
        // Fold RMS 2 and 4: sd sqrt(2), over sqrt(2).
        assert!((se - 1.0).abs() < 1e-15);
    }
}
