use super::*;

/// [`blocks::identity_multiple`] of a stacked matrix and its layout.
fn identity_multiple((stacked, blocks): (&DMatrix<f64>, &Blocks)) -> Option<f64> {
    blocks::identity_multiple(stacked, blocks)
}

/// The multiple `c` of the identity that every block of `weights`' whitened noise is, if so:
/// held as [`RowCovariance::Scale`], or found in the stacked blocks.
fn noise_scale(weights: &Weights) -> Option<f64> {
    match weights.noise()? {
        RowCovariance::Scale(c) => Some(*c),
        RowCovariance::Blocks(stacked) => identity_multiple((stacked, weights.blocks())),
    }
}

/// The stacked blocks of `weights`' whitened noise; panics if they are held as a scale.
fn noise_blocks(weights: &Weights) -> &DMatrix<f64> {
    match weights.noise() {
        Some(RowCovariance::Blocks(stacked)) => stacked,
        other => panic!("expected stacked blocks, found {other:?}"),
    }
}

/// A small system with a known answer: 4 points of 3 rows, 2 parameters.
fn small_system() -> LinearSystem {
    let h = DMatrix::from_fn(12, 2, |r, c| ((r * 7 + c * 3) as f64 * 0.91).sin() + c as f64);
    let y = &h * DVector::from_vec(vec![0.5, -2.0]) + DVector::from_fn(12, |r, _| 0.01 * (r as f64).cos());
    let v = DMatrix::from_fn(12, 3, |r, c| {
        let k = (r / 3) as f64 + 1.0;
        if r % 3 == c { k * k } else { 0.1 * k }
    });
    LinearSystem { h, y, rows_per_point: 3, v: Some(v), names: Vec::new() }
}

#[test]
fn the_papers_normalisation_leaves_the_estimate_unchanged() {
    let system = small_system();
    for estimator in [Estimator::Wls, Estimator::WlsDiag, Estimator::WlsSigma] {
        let solve = |normalise| {
            let weights = Weights::new(system.v.as_ref(), 3, estimator, normalise).unwrap();
            let whitened = weights.whiten(&system);
            (whitened.b.norm(), solve::solve(&whitened, RANK_TOLERANCE, system.column_names()).unwrap())
        };
        let ((a_plain, plain), (a_normalised, normalised)) = (solve(false), solve(true));
        assert!((a_plain - a_normalised).abs() > 1e-3, "{estimator}: the normalisation must scale the rows");
        let change = (&plain.x - &normalised.x).amax() / plain.x.amax();
        assert!(change < 1e-12, "{estimator}: x changed by {change:e}");
        let cov_change = (&plain.covariance - &normalised.covariance).amax() / plain.covariance.amax();
        assert!(cov_change < 1e-12, "{estimator}: covariance changed by {cov_change:e}");
    }
}

#[test]
fn gauss_markov_whitening_gives_identity_noise() {
    let system = small_system();
    let weights = Weights::new(system.v.as_ref(), 3, Estimator::Wls, false).unwrap();
    let noise = weights.whiten(&system).noise.unwrap();
    assert!(matches!(noise, RowCovariance::Scale(c) if (c - 1.0).abs() < 1e-12), "{noise:?}");
    // Held as one number; written out, every block the identity to rounding.
    let reweighted = weights.reweighted(&[1.0; 4]);
    let stacked = noise_blocks(&reweighted);
    for k in 0..4 {
        assert!((stacked.rows(3 * k, 3) - DMatrix::identity(3, 3)).amax() < 1e-12);
    }
}

#[test]
fn estimator_names_round_trip() {
    for e in Estimator::ALL {
        assert_eq!(e.name().parse::<Estimator>().unwrap(), e);
    }
    assert!("gls".parse::<Estimator>().unwrap_err().contains("ols, wls, wls-diag, wls-sigma"));
}

#[test]
fn prepared_estimator_equals_the_one_off_estimate() {
    let system = small_system();
    for estimator in Estimator::ALL {
        let prepared = Prepared::new(&system.h, system.v.as_ref(), 3, estimator, RANK_TOLERANCE).unwrap();
        let once = estimate(&system, estimator, RANK_TOLERANCE).unwrap();
        assert!((prepared.estimate(&system.y) - &once.x).amax() < 1e-14, "{estimator}");
        // The one-off estimate solves the reduced system, the prepared one every row: the
        // same to rounding.
        let (p, o) = (prepared.diagnostics(), &once.diagnostics);
        assert_eq!(
            (p.rank, &p.identifiable, &p.not_identifiable),
            (o.rank, &o.identifiable, &o.not_identifiable)
        );
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs();
        assert!(p.singular_values.iter().zip(&o.singular_values).all(|(x, y)| close(*x, *y)), "{estimator}");
        assert!(close(p.condition_number, o.condition_number), "{estimator}");
    }
}

#[test]
fn diagnose_reports_what_estimate_does() {
    let mut system = small_system();
    // A third column that the first two explain: rank 2, one combination.
    let sum = system.h.column(0) + system.h.column(1) * 2.0;
    system.h = system.h.insert_column(2, 0.0);
    system.h.set_column(2, &sum);
    for estimator in Estimator::ALL {
        let diagnostics = diagnose(&system, estimator, RANK_TOLERANCE).unwrap();
        assert_eq!(diagnostics, estimate(&system, estimator, RANK_TOLERANCE).unwrap().diagnostics);
        assert_eq!((diagnostics.rank, diagnostics.not_identifiable.len()), (2, 1), "{estimator}");
    }
}

/// `S` whitens: `|S_k y_k|^2 = y_k^T V_k^-1 y_k` for every block size (3 and 6 have their own
/// code), applied to a whole matrix or one point's block at a time.
#[test]
fn whitening_gives_the_mahalanobis_norm_for_any_block_size() {
    for b in [3, 6, 9] {
        let points = 5;
        let v = DMatrix::from_fn(points * b, b, |r, c| {
            let k = (r / b) as f64 + 1.0;
            if r % b == c { k * k + c as f64 } else { 0.1 * k }
        });
        let weights = Weights::new(Some(&v), b, Estimator::Wls, false).unwrap();
        let m = DMatrix::from_fn(points * b, 2, |r, c| ((r * 3 + c) as f64 * 0.37).sin());
        let mut whole = m.clone();
        weights.apply(&mut whole);
        for k in 0..points {
            let mut block = m.rows(k * b, b).into_owned();
            weights.apply_point(k, block.as_mut_slice());
            assert_eq!(block, whole.rows(k * b, b), "b = {b}, point {k}: one block as in the whole");
            let v_k = v.rows(k * b, b).into_owned();
            for c in 0..2 {
                let y = m.view((k * b, c), (b, 1)).into_owned();
                let mahalanobis = (y.transpose() * v_k.clone().try_inverse().unwrap() * &y)[(0, 0)];
                let whitened = block.column(c).norm_squared();
                assert!(
                    (whitened - mahalanobis).abs() < 1e-12 * mahalanobis,
                    "b = {b}: {whitened} vs {mahalanobis}"
                );
            }
        }
    }
}

/// Gauss-Markov whitening leaves `sigma_max^2 I` to rounding, which the covariance takes as
/// the Gram matrix; other noise blocks are not mistaken for it.
#[test]
fn whitened_gauss_markov_noise_is_a_multiple_of_the_identity() {
    let system = small_system();
    let weights = Weights::new(system.v.as_ref(), 3, Estimator::Wls, true).unwrap();
    let scale = noise_scale(&weights).expect("sigma_max^2 I");
    let sigma_max2 = (0..12).map(|r| system.v.as_ref().unwrap()[(r, r % 3)]).fold(0.0, f64::max);
    assert!((scale - sigma_max2).abs() < 1e-12 * sigma_max2, "{scale} vs {sigma_max2}");
    let diag = Weights::new(system.v.as_ref(), 3, Estimator::WlsDiag, true).unwrap();
    assert_eq!(noise_scale(&diag), None, "correlated blocks");
    assert_eq!(
        identity_multiple((system.v.as_ref().unwrap(), &Blocks::Uniform(3))),
        None,
        "unequal variances"
    );
    assert_eq!(identity_multiple((&DMatrix::zeros(6, 3), &Blocks::Uniform(3))), None, "zero noise");
}

/// The whitened noise `S_k V_k S_k^T` is written out, block by block, as soon as one block
/// is not `c I`, however many before it were: here the first block is diagonal (WLS-diag
/// whitens it to `I`) and the later ones correlated.
#[test]
fn whitened_noise_is_written_out_when_a_later_block_is_not_a_multiple() {
    let mut v = small_system().v.unwrap();
    for (i, j) in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)] {
        v[(i, j)] = 0.0;
    }
    let weights = Weights::new(Some(&v), 3, Estimator::WlsDiag, false).unwrap();
    let noise = noise_blocks(&weights);
    for k in 0..4 {
        let v_k = v.rows(3 * k, 3);
        let s_k = DMatrix::from_diagonal(&v_k.diagonal().map(|d| d.powf(-0.5)));
        let by_hand = &s_k * v_k * &s_k;
        assert!((noise.rows(3 * k, 3) - &by_hand).amax() < 1e-12, "block {k}: {by_hand}");
        assert!(k == 0 || (by_hand - DMatrix::identity(3, 3)).amax() > 1e-3, "block {k} correlated");
    }
}

/// Ordinary least squares with rows scaled by `S = diag(scale)` is the OLS of `S H`, `S y`,
/// prepared or not, and the covariance of its whitened errors is `S_k V_k S_k`.
#[test]
fn scaled_rows_are_the_ols_of_the_scaled_system() {
    let system = small_system();
    let scale: Vec<f64> = (0..12).map(|r| if r % 3 == 2 { 250.0 } else { 1.0 }).collect();
    let weights = Weights::scaled_rows(system.v.as_ref(), Blocks::Uniform(3), &scale);
    let by_hand = {
        let s = |m: &DMatrix<f64>| DMatrix::from_fn(m.nrows(), m.ncols(), |r, c| m[(r, c)] * scale[r]);
        let y = DMatrix::from_column_slice(12, 1, system.y.as_slice());
        let scaled =
            LinearSystem { h: s(&system.h), y: s(&y).column(0).into_owned(), v: None, ..system.clone() };
        estimate(&scaled, Estimator::Ols, RANK_TOLERANCE).unwrap().x
    };
    let prepared = Prepared::with_weights(&system.h, weights.clone(), RANK_TOLERANCE).unwrap();
    assert!((prepared.estimate(&system.y) - &by_hand).amax() < 1e-12);
    let noise = noise_blocks(&weights);
    let v = system.v.as_ref().unwrap();
    assert!(
        (noise[(5, 2)] - 250.0 * v[(5, 2)] * 250.0).abs() < 1e-9 && (noise[(3, 1)] - v[(3, 1)]).abs() < 1e-12
    );
}

/// Points of different sizes (a pose with three markers, one with a single distance, ...):
/// whitening gives each block's Mahalanobis norm, point by point as in the whole, and Gauss-Markov
/// on the ragged blocks is the dense `(H^T V^-1 H)^-1 H^T V^-1 y` with `V` assembled in full.
#[test]
fn ragged_blocks_whiten_and_estimate_as_the_dense_gauss_markov() {
    let sizes = [3, 1, 6, 2, 4];
    let blocks = Blocks::from_sizes(sizes);
    let (rows, width) = (sizes.iter().sum::<usize>(), blocks.width());
    assert_eq!(
        (blocks.points(rows), width, blocks.covers(rows), blocks.covers(rows + 1)),
        (5, 6, true, false)
    );
    let mut v = DMatrix::zeros(rows, width);
    let mut dense = DMatrix::zeros(rows, rows);
    for r in blocks.ranges(rows) {
        let n = r.len();
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 5 + j * 3 + r.start) as f64 * 0.71).sin());
        let v_k = &a * a.transpose() + DMatrix::identity(n, n) * 0.5;
        v.view_mut((r.start, 0), (n, n)).copy_from(&v_k);
        dense.view_mut((r.start, r.start), (n, n)).copy_from(&v_k);
    }
    assert_eq!(blocks.diagonal(&v), dense.diagonal().as_slice());
    let weights = Weights::of_blocks(Some(&v), blocks.clone(), Estimator::Wls, false).unwrap();
    let mut rng = <rand::rngs::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(7);
    let h = DMatrix::from_fn(rows, 3, |_, _| {
        rand_distr::Distribution::<f64>::sample(&rand_distr::StandardNormal, &mut rng)
    });
    assert_eq!(h.rank(1e-9), 3, "a full-rank H");
    let y = DVector::from_fn(rows, |r, _| ((r * 11) as f64 * 0.13).sin());
    let mut whole = h.clone();
    weights.apply(&mut whole);
    for (k, r) in blocks.ranges(rows).enumerate() {
        let mut block = h.rows(r.start, r.len()).into_owned();
        weights.apply_point(k, block.as_mut_slice());
        assert_eq!(block, whole.rows(r.start, r.len()), "point {k}: one block as in the whole");
    }
    let mut b = y.clone();
    weights.apply(&mut b);
    let v_inv = dense.clone().try_inverse().unwrap();
    let mahalanobis = (y.transpose() * &v_inv * &y)[(0, 0)];
    assert!((b.norm_squared() - mahalanobis).abs() < 1e-10 * mahalanobis);
    let reduced = Reduced::of_whitened(&whole, &b, &blocks, weights.noise());
    let x = solve::factorise_reduced(&reduced, RANK_TOLERANCE).unwrap().solve(&reduced);
    let gls = (h.transpose() * &v_inv * &h).try_inverse().unwrap() * h.transpose() * &v_inv * &y;
    assert!((&x - &gls).amax() < 1e-10 * gls.amax(), "{x} vs {gls}");
    let c = noise_scale(&weights).expect("S_k V_k S_k^T = I in every block");
    assert!((c - 1.0).abs() < 1e-12, "{c}");
    // A point's weight scales its rows only.
    let reweighted = weights.reweighted(&[1.0, 4.0, 1.0, 1.0, 1.0]);
    let mut twice = h.clone();
    reweighted.apply(&mut twice);
    assert!((twice.rows(3, 1) - whole.rows(3, 1) * 2.0).amax() < 1e-12);
    assert!((twice.rows(4, 6) - whole.rows(4, 6)).amax() < 1e-12);
}
