//! The simulated study: calibration runs per second at N_p = 48 (real robot, noisy
//! measurements, OLS, WLS and WLS-diag estimates, each evaluated on 1000 test points), on one
//! thread; one point set of 48 points with 2 runs and with 66 runs, whose difference over 64 is
//! the cost of one run (the point set's `H`, `V` and factorisations excluded); and the wall
//! time of the whole default `reproduce` (both of the paper's studies, tables, CSV and
//! figures, without writing files) on all cores.

use criterion::{Criterion, criterion_group, criterion_main};
use robocal::io::load_study;
use robocal::report;
use robocal::simulation::{self, Case, PoseChoice};

fn simulation(c: &mut Criterion) {
    let mut one_set = load_study("paper-table1").unwrap();
    one_set.cases = vec![Case { points: 48, sigma_me: 0.0, poses: PoseChoice::Random }];
    one_set.point_sets = 1;
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut group = c.benchmark_group("simulation");
    group.sample_size(20);
    group.bench_function("one point set of 48 points and its 16 runs, 1 thread", |b| {
        b.iter(|| single.install(|| simulation::run(&one_set, &|| {}).unwrap()))
    });
    // One run's cost: (66 runs - 2 runs) / 64.
    for runs in [2, 66] {
        let mut study = one_set.clone();
        study.runs_per_set = runs;
        group.bench_function(format!("one point set of 48 points and {runs} runs, 1 thread"), |b| {
            b.iter(|| single.install(|| simulation::run(&study, &|| {}).unwrap()))
        });
    }
    let studies = [load_study("paper-table1").unwrap(), load_study("paper-table2").unwrap()];
    group.sample_size(10);
    group.bench_function("reproduce: both paper studies with tables, CSV and figures", |b| {
        b.iter(|| {
            for study in &studies {
                let results = simulation::run(study, &|| {}).unwrap();
                let _ = report::study::tables(study, &results);
                let _ = report::study::samples_csv(study, &results);
                let _ = report::figures::study_figures(study, &results).unwrap();
            }
        })
    });
    group.finish();
}

criterion_group!(benches, simulation);
criterion_main!(benches);
