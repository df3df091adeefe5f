//! Mark detection on a 256 x 256 frame: `cargo bench -p shared --bench detection`.

use criterion::{criterion_group, criterion_main, Criterion};
use heapless::Vec;
use shared::detection::{Detector, DetectorSettings, GrayImage};
use std::hint::black_box;

/// Light falling across the frame, a faint texture and twelve bright discs
/// of radius 3 to 6 px: the scene a calibration frame shows.
fn frame() -> std::vec::Vec<u8> {
    let mut pixels = vec![0u8; 256 * 256];
    for y in 0..256usize {
        for x in 0..256usize {
            let light = 60.0 + 40.0 * (x + y) as f32 / 256.0;
            let texture = 4.0 * ((x as f32 * 0.7).sin() * (y as f32 * 0.45).cos());
            let mut value = light + texture;
            for k in 0..12 {
                let (cx, cy) = (30.0 + 60.0 * (k % 4) as f32, 40.0 + 80.0 * (k / 4) as f32);
                let r = 3.0 + (k % 4) as f32;
                if (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2) <= r * r {
                    value += 120.0;
                }
            }
            pixels[y * 256 + x] = value.clamp(0.0, 255.0) as u8;
        }
    }
    pixels
}

fn bench(c: &mut Criterion) {
    let pixels = frame();
    let image = match GrayImage::packed(256, 256, &pixels) {
        Ok(image) => image,
        Err(error) => panic!("bench frame: {error}"),
    };
    let mut detector = Box::new(Detector::new(DetectorSettings::default()));
    let mut out = Vec::new();
    c.bench_function("detect marks, 256 x 256 frame", |b| {
        b.iter(|| black_box(detector.detect(black_box(&image), &mut out)))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
