//! The Rust side of `python/benches/bench.py`: the library's forward kinematics of the same
//! configurations `Model.fk_batch` takes, timed the same way (best of 5), as a 4 x 4 transform
//! each. `cargo run --release -p robocal-python --example fk_rust -- 100000`
use robocal::kinematics::Chain;
use robocal::model::RobotModel;
use std::time::Instant;

fn main() {
    let n: usize = std::env::args().nth(1).map_or(100_000, |a| a.parse().expect("a count"));
    let model = RobotModel::preset("puma560").expect("a preset");
    let at = Chain::new(&model).with_errors(&vec![0.0; model.params().len()]);
    // The same configurations as bench.py: q[i, j] = sin(i + j) * 2 rad.
    let q: Vec<f64> = (0..n * 6).map(|k| ((k / 6 + k % 6) as f64).sin() * 2.0).collect();
    let mut best = f64::INFINITY;
    let mut checksum = 0.0;
    for _ in 0..5 {
        let started = Instant::now();
        let mut out = vec![0.0; n * 16];
        for (q, out) in q.chunks_exact(6).zip(out.chunks_exact_mut(16)) {
            let m = at.pose(q).to_homogeneous();
            for (i, v) in out.iter_mut().enumerate() {
                *v = m[(i / 4, i % 4)];
            }
        }
        best = best.min(started.elapsed().as_secs_f64());
        checksum = out.iter().sum::<f64>();
    }
    println!("rust fk of {n} configurations: {:.2} ms (best of 5; checksum {checksum:.6e})", best * 1e3);
}
