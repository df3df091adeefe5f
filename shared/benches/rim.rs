//! The disc's rim measured in a 256 x 256 frame: `cargo bench -p shared --bench rim`.

use criterion::{criterion_group, criterion_main, Criterion};
use shared::detection::identify::lens::LensModel;
use shared::detection::rim::{RimFinder, RimSettings};
use shared::detection::GrayImage;
use std::hint::black_box;

const LENS: LensModel = LensModel {
    f_px: 290.0,
    cx: 127.5,
    cy: 127.5,
    k1: 0.0,
    k2: 0.0,
};

/// A disc of radius 47 px seen at a slant (an ellipse of 47 by 42 px): its
/// surface at 60 grey, a dark band 1.6 px wide at its edge (24 grey) and
/// the floor (50 grey), by 4 x 4 sub-pixels, with a little light gradient
/// and uniform noise of about 2 grey levels drawn from `seed`.
fn frame(seed: u32) -> std::vec::Vec<u8> {
    let mut state = seed.max(1);
    let mut pixels = vec![0u8; 256 * 256];
    let (cx, cy, a, b) = (131.0f32, 124.0f32, 47.0f32, 42.0f32);
    for y in 0..256usize {
        for x in 0..256usize {
            let mut sum = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = x as f32 - 0.375 + 0.25 * sx as f32 - cx;
                    let py = y as f32 - 0.375 + 0.25 * sy as f32 - cy;
                    let s = ((px / a).powi(2) + (py / b).powi(2)).sqrt();
                    sum += if s < 1.0 - 1.6 / 45.0 {
                        60.0
                    } else if s < 1.0 {
                        24.0
                    } else {
                        50.0
                    };
                }
            }
            let light = 1.0 + 0.1 * (x as f32 - 128.0) / 128.0;
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = (state % 7) as f32 - 3.0;
            pixels[y * 256 + x] = (light * sum / 16.0 + noise).clamp(0.0, 255.0) as u8;
        }
    }
    pixels
}

fn bench(c: &mut Criterion) {
    let (first_pixels, pixels) = (frame(0x9e37_79b9), frame(0x85eb_ca6b));
    let packed = |pixels| match GrayImage::packed(256, 256, pixels) {
        Ok(image) => image,
        Err(error) => panic!("bench frame: {error}"),
    };
    let mut finder = Box::new(RimFinder::new(RimSettings::default()));
    let frames = [packed(&first_pixels), packed(&pixels)];
    let start = [131.0, 124.0];
    c.bench_function("rim from the disc centre, 256 x 256 frame", |b| {
        b.iter(|| black_box(finder.find_from_centre(black_box(&frames[1]), &LENS, &[], start)))
    });
    // Tracking: each frame from the last one's fit, the two frames (the
    // noise drawn twice) in turn.
    let mut last = match finder.find_from_centre(&frames[0], &LENS, &[], start) {
        Ok(fit) => fit,
        Err(error) => panic!("bench rim: {error}"),
    };
    let mut next = 1;
    c.bench_function("rim from the last frame's, 256 x 256 frame", |b| {
        b.iter(|| {
            match finder.find_near(black_box(&frames[next]), &LENS, &[], &last, None) {
                Ok(fit) => last = fit,
                Err(error) => panic!("bench rim, next frame: {error}"),
            }
            next = 1 - next;
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
