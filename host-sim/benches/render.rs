//! Speed of rendering one camera frame (256 x 256, the default image
//! settings): the scene of a world at its start, rendered with and without
//! motion, then lit and exposed with noise; and the detector on the result.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use heapless::Vec as HVec;
use host_sim::scenario::pick::PickScenarioFile;
use host_sim::world::render::{build_scene, FrameState, Renderer};
use host_sim::world::World;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use shared::detection::{Detector, DetectorSettings};

fn benches(c: &mut Criterion) {
    let experiment = PickScenarioFile::default_experiment("turning").expect("default scenario");
    let world = World::new(&experiment, 1).expect("world");
    let settings = experiment.image;
    let scene = build_scene(
        world.workcell(),
        &FrameState::from_world(&world, settings.exposure_ms / 1000.0),
        &settings,
    );
    let mut renderer = Renderer::new(world.camera().camera(), &settings).expect("renderer");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut group = c.benchmark_group("camera frame 256 x 256");
    group.bench_function("scene", |b| {
        b.iter(|| {
            build_scene(
                black_box(world.workcell()),
                &FrameState::from_world(&world, 0.008),
                &settings,
            )
        })
    });
    group.bench_function("render, light and noise", |b| {
        b.iter(|| renderer.frame(black_box(&scene), false, &mut rng))
    });
    let frame = renderer.frame(&scene, false, &mut rng);
    let mut detector = Box::new(Detector::new(DetectorSettings::default()));
    let mut blobs = HVec::new();
    group.bench_function("detect", |b| {
        b.iter(|| {
            let image = frame.as_image().expect("image");
            detector
                .detect(black_box(&image), &mut blobs)
                .expect("detect")
        })
    });
    group.finish();
}

criterion_group!(render, benches);
criterion_main!(render);
