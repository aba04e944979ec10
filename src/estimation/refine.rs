//! Nonlinear refinement: the paper's linear step, repeated about the updated parameters
//! (Gauss-Newton), in a trust region (Levenberg-Marquardt, [`super::trust`]): the damping is
//! kept from step to step, lowered after steps that keep the linearised system's promise,
//! raised after those that do not; while Gauss-Newton's steps keep theirs, they are taken as
//! they are. The paper's one-step estimate is the first iterate (`max_iterations = 1`).

use super::prior::PriorRows;
use super::solve::{
    Diagnostics, Factorised, LinearEstimate, RANK_TOLERANCE, diagnose_reduced, factorise_reduced,
};
use super::trust::{self, Region, Steps};
use super::{Blocks, EstimationError, Estimator, Reduced, Weights};
use nalgebra::{DMatrix, DVector};

/// A least-squares problem that can be linearised about any parameter values.
pub trait Residuals {
    /// Rows per point: 3 (position) or 6 (pose).
    fn rows_per_point(&self) -> usize;
    /// How the rows fall into points, one block `V_k` each: by default
    /// [`Residuals::rows_per_point`] rows every point.
    fn blocks(&self) -> Blocks {
        Blocks::Uniform(self.rows_per_point())
    }
    /// Rows of `y`: `N_m`.
    fn equations(&self) -> usize;
    /// Number of parameters: the length of `x`.
    fn parameters(&self) -> usize;
    /// The covariance blocks `V_k`, stacked, held fixed over the iterations; `None` if unknown.
    fn covariance(&self) -> Option<&DMatrix<f64>>;
    /// The name of each parameter (`j3.beta`); by default `x1`, `x2`, ...
    fn names(&self) -> Vec<String> {
        Vec::new()
    }
    /// The factor of each row of `y` (`N_m`) for ordinary least squares, when rows come in
    /// different units (a pose: mm, then rad); `None` (the default): every row counts alike.
    /// See [`Weights::scaled_rows`].
    fn ols_row_scale(&self) -> Option<Vec<f64>> {
        None
    }
    /// The residual `y(x)` (measured minus predicted) and, if `h` is given, the Jacobian
    /// `H(x) = d(prediction)/dx` written into it.
    fn evaluate(&self, x: &DVector<f64>, h: Option<&mut DMatrix<f64>>) -> DVector<f64>;
    /// The whitened residual `S y(x)` and, if `h` is given, `S H(x)` written over all of it.
    /// By default [`Residuals::evaluate`] with the weights applied after; a problem that builds
    /// `H` point by point can whiten each block while it is in cache.
    fn evaluate_whitened(
        &self,
        x: &DVector<f64>,
        weights: &Weights,
        mut h: Option<&mut DMatrix<f64>>,
    ) -> DVector<f64> {
        if let Some(h) = h.as_deref_mut() {
            h.fill(0.0);
        }
        let mut y = self.evaluate(x, h.as_deref_mut());
        if let Some(h) = h {
            weights.apply(h);
        }
        weights.apply(&mut y);
        y
    }
    /// The whitened residual `S y(x)` and the whitened system `[S H(x) S y(x)]` reduced to its
    /// triangular factor ([`Reduced`]), with the covariance of the whitened rows from `weights`.
    /// By default [`Residuals::evaluate_whitened`] into a whole `H`, then reduced; a problem
    /// that builds `H` point by point can reduce each block as it comes and never hold `H`.
    fn linearise_whitened(&self, x: &DVector<f64>, weights: &Weights) -> (DVector<f64>, Reduced) {
        let mut h = DMatrix::zeros(self.equations(), self.parameters());
        let y = self.evaluate_whitened(x, weights, Some(&mut h));
        let reduced = Reduced::of_whitened(&h, &y, weights.blocks(), weights.noise());
        (y, reduced)
    }
}

/// When to stop iterating.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// At most this many linear steps; 1 is the paper's one-step estimate. The default, 200,
    /// converges a draw-wire's flat, curved valley (distances to one point from a tool point
    /// near the last axis, poses from a narrow range) that takes the trust region 50 to 150
    /// steps; a well-posed calibration takes 3 to 10.
    pub max_iterations: usize,
    /// Stop when no whitened residual moves by more than this in a step.
    pub step_tolerance: f64,
    /// Stop when a step lowers the weighted cost by less than this fraction, and take no step
    /// where the linearised system promises a fall below it (the minimum). The default, 1e-10,
    /// stays clear of the cost's rounding (near 1e-12 for a thousand poses), so the number of
    /// steps does not depend on it.
    pub cost_tolerance: f64,
    /// Relative rank tolerance of each linear solve ([`RANK_TOLERANCE`]).
    pub rank_tolerance: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            step_tolerance: 1e-9,
            cost_tolerance: 1e-10,
            rank_tolerance: RANK_TOLERANCE,
        }
    }
}

/// One linear step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Iteration {
    /// Weighted cost before the step.
    pub cost: f64,
    /// Weighted cost after it.
    pub cost_after: f64,
    /// Largest change of a whitened prediction the step made.
    pub step: f64,
    /// The trust region's Levenberg-Marquardt damping `lambda` of the scaled system (0: a plain
    /// Gauss-Newton step; see [`super::trust`]).
    pub damping: f64,
}

/// The refined estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    /// The estimate at the last parameters, with the covariance and the diagnostics (rank,
    /// singular values) of the last linearisation; `estimate.x` holds the parameter values
    /// (not a step).
    pub estimate: LinearEstimate,
    /// Every step taken.
    pub history: Vec<Iteration>,
    /// Whether a stopping rule was met before `max_iterations`.
    pub converged: bool,
}

/// The whitened system of a problem about `x`: `A = S H(x)` and `b = S y(x)` (Eq. 1,
/// weighted as in Eq. 4), `A` held only as the triangular factor of `[A b]` ([`Reduced`]).
#[derive(Debug, Clone)]
pub struct Linearisation {
    /// Where the problem was linearised.
    pub x: DVector<f64>,
    /// `S y(x)`, `N_m`.
    pub b: DVector<f64>,
    /// `[S H(x) S y(x)]` reduced: `p + 1` numbers a column, whatever `N_m`.
    pub system: Reduced,
}

impl Linearisation {
    /// The same system for a problem that keeps only `columns` (ascending) of the parameters:
    /// what the identifiable subset starts from, without linearising again.
    pub fn select(&self, columns: &[usize]) -> Self {
        Self { x: self.x.select_rows(columns), b: self.b.clone(), system: self.system.select(columns) }
    }

    /// The system with the prior rows `c P` below it ([`PriorRows::augment`]): what can be
    /// identified once the priors are counted.
    pub fn with_prior(&self, prior: &PriorRows) -> Self {
        Self { x: self.x.clone(), b: self.b.clone(), system: self.system.with_prior(prior, &self.x) }
    }

    /// The norms of the columns of `A`, one a parameter.
    pub fn column_norms(&self) -> Vec<f64> {
        self.system.column_norms()
    }

    /// What the system can identify: rank, identifiable subset, non-identifiable combinations
    /// (as [`super::diagnose`], which starts from an unweighted system).
    pub fn diagnose(&self, rank_tolerance: f64) -> Result<Diagnostics, EstimationError> {
        diagnose_reduced(&self.system, rank_tolerance, &[], false)
    }

    /// [`Linearisation::diagnose`], with the identifiable columns chosen class by class of
    /// `priority` (one class per column, 0 first): of a combination the columns cannot tell
    /// apart, the one of the latest class is held.
    pub fn diagnose_by_priority(
        &self,
        rank_tolerance: f64,
        priority: &[u32],
    ) -> Result<Diagnostics, EstimationError> {
        diagnose_reduced(&self.system, rank_tolerance, priority, false)
    }

    /// [`Linearisation::diagnose_by_priority`] of the data alone of a fit anchored by priors:
    /// fewer equations than parameters are diagnosed (the rank is then at most the number of
    /// equations), not refused, as the priors identify the rest.
    pub fn diagnose_data_alone(
        &self,
        rank_tolerance: f64,
        priority: &[u32],
    ) -> Result<Diagnostics, EstimationError> {
        diagnose_reduced(&self.system, rank_tolerance, priority, true)
    }
}

impl Weights {
    /// The weights of `estimator` for the covariance blocks of `problem` (checked: sizes,
    /// finite values, symmetric blocks), with the paper's normalisation; ordinary least
    /// squares scales the rows of a problem whose points mix units
    /// ([`Residuals::ols_row_scale`], [`Weights::scaled_rows`]).
    pub fn for_problem(problem: &impl Residuals, estimator: Estimator) -> Result<Self, EstimationError> {
        let blocks = problem.blocks();
        let equations = problem.equations();
        if !blocks.covers(equations) {
            return Err(EstimationError::Dimensions(format!(
                "{equations} equations in points of {blocks:?}"
            )));
        }
        if let Some(v) = problem.covariance() {
            if v.shape() != (equations, blocks.width()) {
                return Err(EstimationError::Dimensions(format!(
                    "V blocks are {:?}, expected {equations} x {}",
                    v.shape(),
                    blocks.width()
                )));
            }
            super::check_covariance(v, &blocks)?;
        }
        match (estimator, problem.ols_row_scale()) {
            (Estimator::Ols, Some(scale)) if scale.len() == equations => {
                Ok(Weights::scaled_rows(problem.covariance(), blocks, &scale))
            }
            _ => Weights::of_blocks(problem.covariance(), blocks, estimator, true),
        }
    }

    /// [`Weights::for_problem`]'s ordinary least squares without the noise: the same rows, so
    /// the same fit to the bit, but no covariance of the whitened rows is held or summed (the
    /// estimate's covariance then comes from the residuals). For a fit whose values alone are
    /// used, such as a calibration's "before" fit, where the noise would cost a copy of `V`
    /// and a `p x p` product per point in every linearisation.
    pub fn ols_without_noise(problem: &impl Residuals) -> Self {
        let blocks = problem.blocks();
        match problem.ols_row_scale() {
            Some(scale) if scale.len() == problem.equations() => Weights::scaled_rows(None, blocks, &scale),
            _ => Weights { s: None, noise: None, blocks, scale: None, whitened: false },
        }
    }
}

/// Whether `x` and `weights` fit `problem`.
fn check_linearisable(
    problem: &impl Residuals,
    weights: &Weights,
    x: &DVector<f64>,
) -> Result<(), EstimationError> {
    let dims = |s: String| Err(EstimationError::Dimensions(s));
    if x.len() != problem.parameters() {
        return dims(format!("{} start values for {} parameters", x.len(), problem.parameters()));
    }
    if !weights.fits(problem.equations(), &problem.blocks()) {
        return dims(format!(
            "weights for other points than the problem's {} equations",
            problem.equations()
        ));
    }
    Ok(())
}

/// `problem` linearised about `x` and whitened by `weights` (from [`Weights::for_problem`]),
/// with every size and value checked.
pub fn linearise(
    problem: &impl Residuals,
    weights: &Weights,
    x: DVector<f64>,
) -> Result<Linearisation, EstimationError> {
    check_linearisable(problem, weights, &x)?;
    let (b, system) = problem.linearise_whitened(&x, weights);
    system.check_finite()?;
    Ok(Linearisation { x, b, system })
}

/// Refine `x0` by Gauss-Newton in a trust region (Levenberg-Marquardt, [`super::trust`]),
/// each step the weighted (or ordinary) least-squares solution of the system linearised about
/// the current `x`, damped when the region is shorter than it.
pub fn refine(
    problem: &impl Residuals,
    estimator: Estimator,
    x0: DVector<f64>,
    options: &RefineOptions,
) -> Result<Refined, EstimationError> {
    let weights = Weights::for_problem(problem, estimator)?;
    let start = linearise(problem, &weights, x0)?;
    refine_from(problem, &weights, start, options)
}

/// [`refine`] from a linearisation already made with the same `weights`: stages of one
/// calibration share their weights, and the identifiable subset starts from the system that
/// found it ([`Linearisation::select`]).
pub fn refine_from(
    problem: &impl Residuals,
    weights: &Weights,
    start: Linearisation,
    options: &RefineOptions,
) -> Result<Refined, EstimationError> {
    refine_within(problem, weights, start, options, None, options.max_iterations)
}

/// [`refine_from`] with priors: the maximum a posteriori estimate, each step the least-squares
/// solution of the whitened system with the prior rows `c P` below it ([`PriorRows`], one per
/// column of `problem`; see [`super::prior`]). The covariance is the posterior one,
/// `(H^T V^-1 H + P^2)^-1` for Gauss-Markov (a sandwich for the others); the cost includes the
/// prior's part `|c P x|^2`; the diagnostics are those of the stacked system.
pub fn refine_map(
    problem: &impl Residuals,
    weights: &Weights,
    start: Linearisation,
    options: &RefineOptions,
    prior: &PriorRows,
) -> Result<Refined, EstimationError> {
    refine_within(problem, weights, start, options, Some(prior), options.max_iterations)
}

/// Whether `prior` has one column per parameter of `problem`.
fn check_prior(problem: &impl Residuals, prior: &PriorRows) -> Result<(), EstimationError> {
    if prior.columns() != problem.parameters() {
        return Err(EstimationError::Dimensions(format!(
            "priors for {} columns of a problem of {}",
            prior.columns(),
            problem.parameters()
        )));
    }
    Ok(())
}

/// What [`refine_within`] works on: the problem, its weights and priors, and when to stop.
struct Context<'a, P> {
    problem: &'a P,
    weights: &'a Weights,
    options: &'a RefineOptions,
    prior: Option<&'a PriorRows>,
}

impl<P: Residuals> Context<'_, P> {
    /// The cost at `x` whose whitened residual is `y`: `|y|^2`, with the prior's `|c P x|^2`.
    fn cost(&self, x: &DVector<f64>, y: &DVector<f64>) -> f64 {
        y.norm_squared() + self.prior.map_or(0.0, |p| p.cost(x))
    }

    /// Whether `start`, the weights and the names fit the problem; the names.
    fn check(&self, start: &Linearisation) -> Result<Vec<String>, EstimationError> {
        let (m, p) = (self.problem.equations(), self.problem.parameters());
        let dims = |s: String| Err(EstimationError::Dimensions(s));
        let system = &start.system;
        if system.parameters() != p || system.rows() != m || start.b.len() != m || start.x.len() != p {
            let (rows, columns) = (system.rows(), system.parameters());
            return dims(format!("a linearisation of ({rows}, {columns}) for a problem of {m} x {p}"));
        }
        if !self.weights.fits(m, &self.problem.blocks()) {
            return dims(format!("weights for other points than the problem's {m} equations"));
        }
        let names = self.problem.names();
        if !names.is_empty() && names.len() != p {
            return dims(format!("{} names for {p} parameters", names.len()));
        }
        Ok(super::column_names(names, p))
    }

    /// The trials of one linearisation (`system`, the prior rows below it, factored as
    /// `factorised`) about `x` of cost `cost`, each damped by the trust `region` ([`super::trust`])
    /// and the region moved by its gain, until one does not raise the cost; `None` where no step
    /// is taken: at the minimum, where the Gauss-Newton step promises a fall below the cost
    /// tolerance (a step would move the estimate by rounding, and whether rounding lowers the
    /// cost or raises it would decide whether it is taken), or once the region has collapsed
    /// below the step tolerance. Each trial is linearised at once: an accepted one is the next
    /// step's system.
    fn trials(
        &self,
        x: &DVector<f64>,
        cost: f64,
        system: &Reduced,
        factorised: &Factorised,
        region: &mut Region,
    ) -> Option<Accepted> {
        let steps = Steps::new(factorised, system);
        let promised = cost - system.cost_after(&steps.step(0.0));
        if promised <= self.options.cost_tolerance * cost {
            return None;
        }
        loop {
            let damping = region.damping(&steps.spectrum);
            let step = steps.step(damping);
            let moved_to = x + &step;
            let (y, next) = self.problem.linearise_whitened(&moved_to, self.weights);
            let cost_after = self.cost(&moved_to, &y);
            let gain = trust::gain(cost, cost_after, system.cost_after(&step));
            region.update(gain, steps.spectrum.length(damping));
            if cost_after <= cost {
                let residual = Some((y, next));
                return Some(Accepted { step, cost_after, damping, residual, gain });
            }
            if region.collapsed(&steps.spectrum, self.options.step_tolerance) {
                return None;
            }
        }
    }
}

/// [`refine_from`], or [`refine_map`] with a prior: Levenberg-Marquardt in a trust region
/// ([`super::trust`]) on the whitened system, with the prior rows below it if given, in at most
/// `budget` steps (at least 1; `options.max_iterations` but for a robust fit's reweightings,
/// which share one limit). `options.max_iterations = 1` is the paper's one undamped step.
pub(crate) fn refine_within(
    problem: &impl Residuals,
    weights: &Weights,
    start: Linearisation,
    options: &RefineOptions,
    prior: Option<&PriorRows>,
    budget: usize,
) -> Result<Refined, EstimationError> {
    if let Some(prior) = prior {
        check_prior(problem, prior)?;
    }
    let budget = budget.max(1);
    let context = Context { problem, weights, options, prior };
    let names = context.check(&start)?;
    // The current system, never held whole: its triangular factor and its residual.
    let Linearisation { mut x, mut b, mut system } = start;
    let mut history = Vec::new();
    let mut region = Region::default();
    let one_step = options.max_iterations == 1;
    loop {
        // The stacked system (the data's alone without a prior).
        let stacked = prior.map(|p| system.with_prior(p, &x));
        let ss = stacked.as_ref().unwrap_or(&system);
        let factorised = factorise_reduced(ss, options.rank_tolerance)?;
        let cost = context.cost(&x, &b);
        let taken = if one_step {
            // The paper's estimate: the linear solution, taken as it is; its cost is the
            // linearised residual's.
            let step = factorised.solve(ss);
            let cost_after = ss.cost_after(&step);
            Some(Accepted { step, cost_after, damping: 0.0, residual: None, gain: 1.0 })
        } else {
            context.trials(&x, cost, ss, &factorised, &mut region)
        };
        let (converged, final_cost, next) = match taken {
            Some(accepted) => {
                // How far the step moved a whitened prediction: the change of the whitened
                // residuals (those after the paper's one step are evaluated for it alone).
                let moved = match &accepted.residual {
                    Some((y, _)) => (y - &b).amax(),
                    None => (problem.evaluate_whitened(&(&x + &accepted.step), weights, None) - &b).amax(),
                };
                x += &accepted.step;
                let Accepted { cost_after, damping, .. } = accepted;
                history.push(Iteration { cost, cost_after, step: moved, damping });
                (!one_step && accepted.stops(options, cost, moved), cost_after, accepted.residual)
            }
            None => (true, cost, None),
        };
        match next {
            Some((y, next)) if !converged && history.len() < budget => {
                super::finite("y", y.as_slice(), y.len())?;
                next.check_finite()?;
                system = next;
                b = y;
            }
            _ => {
                let covariance = match prior {
                    None => factorised.covariance(&system, final_cost),
                    Some(prior) => factorised.posterior_covariance(&system, prior),
                };
                let diagnostics = factorised.diagnostics;
                let estimate = LinearEstimate { names, x, covariance, cost: final_cost, diagnostics };
                return Ok(Refined { estimate, history, converged });
            }
        }
    }
}

/// A step that did not raise the cost.
struct Accepted {
    step: DVector<f64>,
    cost_after: f64,
    /// The trust region's damping (0: the Gauss-Newton step).
    damping: f64,
    /// `S y` after the step and the system linearised there; `None` for the paper's one step.
    residual: Option<(DVector<f64>, Reduced)>,
    /// Its gain ratio ([`trust::gain`]).
    gain: f64,
}

impl Accepted {
    /// Whether the stopping rules are met after the step, of cost `cost` before it, that moved
    /// a whitened prediction by `moved` at most: a Gauss-Newton step (undamped) that moved none
    /// by more than the step tolerance, or that lowered the cost by less than the cost tolerance
    /// (a fraction of it) and kept a quarter of its promise at least (a step that jumped across
    /// a valley to as high a cost promised much and lowered little, and says nothing of a
    /// minimum). A step the region cut short (damped) stops nothing: the next linearisation
    /// finds the minimum ([`Context::trials`]).
    fn stops(&self, options: &RefineOptions, cost: f64, moved: f64) -> bool {
        let undamped = self.damping == 0.0;
        let still = moved <= options.step_tolerance;
        let flat = cost - self.cost_after <= options.cost_tolerance * cost && self.gain >= 0.25;
        undamped && (still || flat)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One point measuring `atan(x)` in its first coordinate, observed as 0: Gauss-Newton
    /// from x = 3 overshoots (it diverges for |x| > 1.39), so damping must take over.
    struct Arctangent;

    impl Residuals for Arctangent {
        fn rows_per_point(&self) -> usize {
            3
        }
        fn equations(&self) -> usize {
            3
        }
        fn parameters(&self) -> usize {
            1
        }
        fn covariance(&self) -> Option<&DMatrix<f64>> {
            None
        }
        fn evaluate(&self, x: &DVector<f64>, h: Option<&mut DMatrix<f64>>) -> DVector<f64> {
            if let Some(h) = h {
                h.fill(0.0);
                h[(0, 0)] = 1.0 / (1.0 + x[0] * x[0]);
            }
            DVector::from_vec(vec![-x[0].atan(), 0.0, 0.0])
        }
    }

    #[test]
    fn damping_rescues_a_diverging_gauss_newton() {
        let start = DVector::from_vec(vec![3.0]);
        let refined = refine(&Arctangent, Estimator::Ols, start.clone(), &RefineOptions::default()).unwrap();
        assert!(refined.converged && refined.estimate.x[0].abs() < 1e-8, "{:?}", refined.history);
        assert!(refined.history[0].damping > 0.0, "the first step needs damping: {:?}", refined.history);
        assert!(refined.history.windows(2).all(|w| w[1].cost <= w[0].cost), "the cost never rises");

        let one = RefineOptions { max_iterations: 1, ..RefineOptions::default() };
        let paper = refine(&Arctangent, Estimator::Ols, start.clone(), &one).unwrap();
        assert!((paper.estimate.x[0] - (3.0 - 3f64.atan() * 10.0)).abs() < 1e-12, "one undamped step");
    }

    /// Gauss-Newton as it was before the trust region: every step tries the Gauss-Newton step,
    /// then Marquardt's damping 1e-4, 1e-3, ... (from 0 again at every step) until the cost does
    /// not rise; it stops when a step moves no whitened residual by more than the step
    /// tolerance or lowers the cost by less than the cost tolerance, or when no damping lowers
    /// it. The end point, its steps and whether a stopping rule was met.
    fn reset_damping(problem: &impl Residuals, x0: f64, options: &RefineOptions) -> (f64, usize, bool) {
        let weights = Weights::for_problem(problem, Estimator::Ols).unwrap();
        let mut x = DVector::from_vec(vec![x0]);
        for steps in 1..=options.max_iterations {
            let (b, system) = problem.linearise_whitened(&x, &weights);
            let cost = b.norm_squared();
            let mut damping: f64 = 0.0;
            let (step, y) = loop {
                let damped = if damping == 0.0 { system.clone() } else { system.damped(damping) };
                let step = factorise_reduced(&damped, options.rank_tolerance).unwrap().solve(&damped);
                let y = problem.evaluate_whitened(&(&x + &step), &weights, None);
                if y.norm_squared() <= cost || damping >= 1e12 {
                    break (step, y);
                }
                damping = if damping == 0.0 { 1e-4 } else { damping * 10.0 };
            };
            if y.norm_squared() > cost {
                return (x[0], steps, true);
            }
            x += step;
            let fall = cost - y.norm_squared();
            if (&y - &b).amax() <= options.step_tolerance || fall <= options.cost_tolerance * cost {
                return (x[0], steps, true);
            }
        }
        (x[0], options.max_iterations, false)
    }

    /// The arctangent's Gauss-Newton map `x -> x - atan(x) (1 + x^2)` has a cycle `x* -> -x*`
    /// (`x* = 1.3917...`, where `atan(x)(1 + x^2) = 2x`). Started just inside it, every
    /// Gauss-Newton step jumps across the valley `atan(x)^2` to nearly the same height: the
    /// cost falls, by a fraction near 1e-11, so Gauss-Newton with damping reset at every step
    /// takes the step and stops there, "converged" at `|x| = 1.39`, the valley's wall. The
    /// trust region sees the step keep none of its promise (gain near 0), shrinks, and goes down
    /// to the minimum at 0.
    #[test]
    fn the_trust_region_leaves_a_valley_that_stalls_gauss_newton() {
        let cycle = |x: f64| x.atan() * (1.0 + x * x) - 2.0 * x;
        let (mut low, mut high) = (1.0, 2.0);
        for _ in 0..200 {
            let mid = 0.5 * (low + high);
            if cycle(mid) < 0.0 { low = mid } else { high = mid }
        }
        let start = low - 1e-11;
        let options = RefineOptions::default();
        let (stalled, steps, stopped) = reset_damping(&Arctangent, start, &options);
        assert!(stopped && steps == 1 && (stalled.abs() - 1.3917).abs() < 1e-3, "{stalled} in {steps}");
        let refined = refine(&Arctangent, Estimator::Ols, DVector::from_vec(vec![start]), &options).unwrap();
        assert!(refined.converged && refined.estimate.x[0].abs() < 1e-8, "{:?}", refined.history);
        assert!(refined.history.iter().any(|i| i.damping > 0.0), "{:?}", refined.history);
        // From x = 3 both converge; the reset damping tries from nothing at every step.
        let (x, _, stopped) = reset_damping(&Arctangent, 3.0, &options);
        assert!(stopped && x.abs() < 1e-8);
    }
}
