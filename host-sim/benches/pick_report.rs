//! Speed of writing one pick's outputs: the four PNG figures alone, and all
//! of them with the CSV files, for a synthetic 60 s run sampled at 100 Hz
//! (6000 records, decimated to about 2000 points per series in the figures).
//! The last outputs are left in `target/pick-report-bench/` to look at.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::pick::outputs::write_run_outputs;
use host_sim::pick::plots::write_run_plots;
use host_sim::pick::synthetic::synthetic_run;

fn benches(c: &mut Criterion) {
    let run = synthetic_run("experiment-1", 6000);
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/pick-report-bench");
    let plots_dir = out.join("plots-only");
    std::fs::create_dir_all(&plots_dir).expect("bench output folder");

    let mut group = c.benchmark_group("pick report (6000 records)");
    group.sample_size(10);
    group.bench_function("four PNG figures", |b| {
        b.iter(|| write_run_plots(black_box(&run), &plots_dir).expect("plots"))
    });
    group.bench_function("CSV files and PNG figures", |b| {
        b.iter(|| write_run_outputs(black_box(&run), &out).expect("outputs"))
    });
    group.finish();
}

criterion_group!(pick_report, benches);
criterion_main!(pick_report);
