//! The label pictures: drawn where the labels are and nowhere else, in the
//! label's colour, wrong labels boxed; and written end to end for a rendered
//! pick, PNGs and GIF at the expected size.

use std::fs::File;

use shared::detection::identify::{LabelledPoint, MarkLabel};
use shared::detection::Blob;

use super::*;
use crate::camera_recording::simulate::{read_truth, record_pick, TrueFrame, TrueMark};
use crate::front_end::score::Judge;
use crate::overlay::animation::OVERLAY_COLOURS;
use crate::scenario::pick::PickScenarioFile;
use crate::vision_check::trial_seed;

fn blob(x: f32, y: f32) -> Blob {
    Blob {
        x_px: x,
        y_px: y,
        area_px: 20,
        semi_major_px: 2.5,
        semi_minor_px: 2.5,
        orientation_rad: 0.0,
        peak_contrast: 120,
        mean_contrast: 100.0,
        lopsidedness: 0.0,
    }
}

fn point(label: MarkLabel, blob: usize) -> LabelledPoint {
    LabelledPoint {
        label,
        pixel: [0.0, 0.0],
        blob,
    }
}

/// Canvas pixels of `colour` within `within` canvas pixels of image point `(u, v)`.
fn count_near(canvas: &Canvas, u: f32, v: f32, within: f64, colour: Rgb) -> usize {
    let (cx, cy) = (canvas.at(f64::from(u)), canvas.at(f64::from(v)));
    let mut n = 0;
    for y in 0..canvas.height {
        for x in 0..canvas.width {
            let d = (x as f64 - cx).hypot(y as f64 - cy);
            if d <= within && canvas.pixel(x, y) == Some(colour) {
                n += 1;
            }
        }
    }
    n
}

#[test]
fn every_colour_drawn_is_in_the_animations_palette() {
    for colour in [
        DISC_CENTRE_COLOUR,
        REFERENCE_COLOUR,
        PART_FEATURE_COLOUR,
        EFFECTOR_COLOUR,
        WRONG_COLOUR,
        OFF_COLOUR,
    ] {
        assert!(OVERLAY_COLOURS.contains(&colour), "{colour:?}");
    }
}

#[test]
fn labels_are_drawn_in_their_colour_at_their_blob_and_nowhere_else() {
    let (width, height) = (80, 60);
    let plain = Canvas::from_gray(width, height, &vec![40; width * height], 3).unwrap();
    let frame = FrameLabels {
        trigger_id: 7,
        blobs: vec![blob(20.0, 30.0), blob(50.0, 30.0), blob(65.0, 45.0)],
        points: vec![
            point(MarkLabel::Reference, 0),
            point(MarkLabel::PartFeature(2), 1),
        ],
        rim: None,
    };
    let mut canvas = plain.clone();
    draw_labels(
        &mut canvas,
        &frame,
        &[Some(Verdict::Right), Some(Verdict::Wrong)],
    );
    // The reference's circle (radius 4.5 px = 13.5 canvas px) in yellow, right of its blob.
    let ring = 4.5 * 3.0;
    assert_eq!(
        canvas.pixel(
            (canvas.at(20.0) + ring + 0.5) as usize,
            canvas.at(30.0) as usize
        ),
        Some(REFERENCE_COLOUR)
    );
    assert!(count_near(&canvas, 20.0, 30.0, 50.0, REFERENCE_COLOUR) > 80);
    assert_eq!(count_near(&canvas, 20.0, 30.0, 50.0, WRONG_COLOUR), 0);
    // The feature: green, boxed in red as wrong.
    assert!(count_near(&canvas, 50.0, 30.0, 50.0, PART_FEATURE_COLOUR) > 80);
    assert!(count_near(&canvas, 50.0, 30.0, 25.0, WRONG_COLOUR) > 80);
    // The unlabelled blob: grey, no label colour.
    assert!(count_near(&canvas, 65.0, 45.0, 16.0, UNLABELLED_COLOUR) > 40);
    for colour in [REFERENCE_COLOUR, PART_FEATURE_COLOUR, WRONG_COLOUR] {
        assert_eq!(
            count_near(&canvas, 65.0, 45.0, 16.0, colour),
            0,
            "{colour:?}"
        );
    }
    // Nothing changed far from the blobs (the text stays within 45 canvas px
    // when it has room up and right).
    for y in 0..canvas.height {
        for x in 0..canvas.width {
            let near = frame.blobs.iter().any(|b| {
                (x as f64 - canvas.at(f64::from(b.x_px)))
                    .hypot(y as f64 - canvas.at(f64::from(b.y_px)))
                    < 45.0
            });
            if !near {
                assert_eq!(canvas.pixel(x, y), plain.pixel(x, y), "({x}, {y})");
            }
        }
    }
    // Without the truth the same frame has no red box.
    let mut unjudged = plain.clone();
    draw_labels(&mut unjudged, &frame, &[]);
    assert_eq!(count_near(&unjudged, 50.0, 30.0, 25.0, WRONG_COLOUR), 0);
    assert!(count_near(&unjudged, 50.0, 30.0, 50.0, PART_FEATURE_COLOUR) > 80);
}

#[test]
fn the_busiest_stretch_is_chosen_wrong_labels_first() {
    let frame = |id: u64, labels: usize| FrameLabels {
        trigger_id: id,
        blobs: vec![blob(10.0, 10.0); 3],
        points: (0..labels)
            .map(|_| point(MarkLabel::DiscCentre, 0))
            .collect(),
        rim: None,
    };
    let frames: Vec<FrameLabels> = [0, 1, 3, 3, 0, 4, 4, 4]
        .iter()
        .enumerate()
        .map(|(i, &n)| frame(i as u64, n))
        .collect();
    // Windows of two: 1, 4, 6, 3, 4, 8, 8: the first of the two best.
    assert_eq!(busiest_stretch(&frames, None, 2), 5);
    assert_eq!(busiest_stretch(&frames, None, 3), 5);
    assert_eq!(busiest_stretch(&frames[..5], None, 2), 2);
    assert_eq!(busiest_stretch(&frames, None, 100), 0);
    // With the truth, the stretch holding the one wrong label (frame 3's
    // centre label, where the true centre is elsewhere) wins over more labels.
    let truth: Vec<TrueFrame> = frames
        .iter()
        .map(|f| TrueFrame {
            trigger_id: f.trigger_id,
            marks: vec![TrueMark {
                kind: "disc_center".into(),
                index: 0,
                image_px: [0.0, 0.0],
                pinhole_px: if f.trigger_id == 3 {
                    [50.0, 50.0]
                } else {
                    [0.0, 0.0]
                },
                visible: true,
                shows: true,
            }],
            rim_pinhole_px: Vec::new(),
        })
        .collect();
    let judge = Judge::new(&frames, &truth);
    assert_eq!(busiest_stretch(&frames, Some(&judge), 2), 2);
    assert_eq!(busiest_stretch(&frames, Some(&judge), 3), 1);
    assert_eq!(busiest_stretch(&[], None, 5), 0);
}

#[test]
fn a_gif_delay_follows_the_capture_interval() {
    assert_eq!(delay_cs(200_000), 20);
    assert_eq!(delay_cs(0), 2);
    assert_eq!(delay_cs(60_000_000), 500);
}

#[test]
fn a_rendered_picks_pictures_show_its_labels() {
    let experiment = PickScenarioFile::default_experiment("turning").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let recording_dir = dir.path().join("rec");
    record_pick(&experiment, trial_seed(1, 0), &recording_dir, 40, 1).unwrap();
    let recording = Recording::open(&recording_dir).unwrap();
    let run = crate::front_end::run(&recording, false).unwrap();
    let truth = read_truth(&recording_dir).unwrap();
    let judge = Judge::new(&run.frames, &truth);
    let options = PictureOptions {
        folder: dir.path().join("pictures"),
        frames: 6,
        first_frame: None,
        scale: 3,
        indexed: false,
    };
    let written = write_pictures(&recording, &run, Some(&judge), &options).unwrap();
    assert_eq!(written.pngs.len(), 6);
    // The busiest stretch is late, where every track is labelled.
    assert!(written.first_frame >= 20, "{}", written.first_frame);
    let (w, h) = (256 * 3, 256 * 3);
    let mut labelled_seen = 0;
    for (k, path) in written.pngs.iter().enumerate() {
        let decoder = png::Decoder::new(std::io::BufReader::new(File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut rgb = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut rgb).unwrap();
        assert_eq!((info.width as usize, info.height as usize), (w, h));
        let picture = Canvas {
            width: w,
            height: h,
            scale: 3,
            rgb,
        };
        let frame = &run.frames[written.first_frame + k];
        let row = recording
            .rows
            .iter()
            .find(|r| r.trigger_id == frame.trigger_id)
            .unwrap();
        let plain = Canvas::from_gray(256, 256, &recording.image(row).unwrap(), 3).unwrap();
        // Each label's colour is drawn about its blob.
        for p in &frame.points {
            let b = frame.blobs[p.blob];
            let radius = (f64::from(b.semi_major_px) + 2.0) * 3.0 + 3.0;
            assert!(
                count_near(&picture, b.x_px, b.y_px, radius, label_colour(p.label)) > 20,
                "{p:?}"
            );
            labelled_seen += 1;
        }
        // What differs from the plain frame is near a blob or in the caption and legend bands.
        let band = text_height(2) + 4;
        for y in band..h - band {
            for x in 0..w {
                if picture.pixel(x, y) != plain.pixel(x, y) {
                    let near = frame.blobs.iter().any(|b| {
                        (x as f64 - picture.at(f64::from(b.x_px)))
                            .hypot(y as f64 - picture.at(f64::from(b.y_px)))
                            < 90.0
                    });
                    assert!(near, "frame {k}: ({x}, {y}) changed far from any blob");
                }
            }
        }
    }
    assert!(labelled_seen >= 12, "{labelled_seen} labels in 6 frames");
    // The animation: the same six frames, at the recording's 5 Hz.
    let mut decoder = gif::DecodeOptions::new()
        .read_info(File::open(&written.animation).unwrap())
        .unwrap();
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!((frame.width as usize, frame.height as usize), (w, h));
        assert_eq!(frame.delay, 20);
        frames += 1;
    }
    assert_eq!(frames, 6);
    // A first frame past the end is refused.
    let late = PictureOptions {
        first_frame: Some(run.frames.len()),
        ..options
    };
    assert!(write_pictures(&recording, &run, None, &late).is_err());
}

#[test]
fn a_label_text_keeps_off_the_texts_and_circles_already_placed() {
    let (centre, r, size) = ((100.0, 100.0), 10.0, (20.0, 14.0));
    let free = place_text(centre, r, size, &[]);
    // Up and right of the circle when free.
    assert!(free[0] > 100.0 && free[3] < 100.0, "{free:?}");
    let mut taken = vec![free];
    for _ in 0..6 {
        let next = place_text(centre, r, size, &taken);
        assert!(
            taken.iter().all(|t| !overlaps(&next, t)),
            "{next:?} on {taken:?}"
        );
        taken.push(next);
    }
    // With every place taken, the one covering fewest.
    let crowded = place_text(centre, r, size, &[[0.0, 0.0, 200.0, 200.0]]);
    assert_eq!(crowded, free);
}
