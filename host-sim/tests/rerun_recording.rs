//! `host-sim run --rerun FILE.rrd` (the `rerun` feature): a short pick
//! through images written as a Rerun recording, read back with Rerun's own
//! decoder.
#![cfg(feature = "rerun")]

use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::{BufReader, Read};

use host_sim::commands::run::{run, Args};
use host_sim::rerun_view::names;
use host_sim::scenario::pick::CameraSource;
use rerun::external::re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};

/// The first bytes of an .rrd file (`re_log_encoding::rrd::RRD_FOURCC`).
const RRD_MAGIC: &[u8; 4] = b"RRF2";

#[test]
fn a_short_pick_through_images_is_recorded_for_the_viewer() {
    let dir = tempfile::tempdir().unwrap();
    // The default run's turning pick, through images (about 5 s here).
    let recording = dir.path().join("pick.rrd");
    run(&Args {
        experiment: vec!["turning".to_string()],
        no_plots: true,
        camera_source: Some(CameraSource::Images),
        rerun: Some(recording.clone()),
        ..Args::default()
    })
    .unwrap();

    let mut magic = [0u8; 4];
    File::open(&recording)
        .unwrap()
        .read_exact(&mut magic)
        .unwrap();
    assert_eq!(&magic, RRD_MAGIC);

    // Rows per entity path, and the timelines each path was logged on.
    let mut rows: BTreeMap<String, usize> = BTreeMap::new();
    let mut timelines: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let messages = DecoderApp::decode_eager(BufReader::new(File::open(&recording).unwrap()))
        .expect("an .rrd file Rerun decodes");
    for message in messages {
        if let LogMsg::ArrowMsg(_, arrow) = message.expect("a whole message") {
            let chunk = Chunk::from_arrow_msg(&arrow).expect("a chunk");
            let path = chunk.entity_path().to_string();
            *rows.entry(path.clone()).or_default() += chunk.num_rows();
            timelines
                .entry(path)
                .or_default()
                .extend(chunk.timelines().keys().map(|name| name.to_string()));
        }
    }
    let rows_of = |entity: &str| rows.get(&format!("/{entity}")).copied().unwrap_or(0);
    let timelines_of = |entity: &str| {
        timelines
            .get(&format!("/{entity}"))
            .cloned()
            .unwrap_or_default()
    };
    for fixed in [names::CELL, names::DISC, names::DROP_OFF] {
        assert!(rows_of(fixed) > 0, "{fixed} missing: {rows:?}");
    }
    // The moving cell at 50 Hz.
    for moving in [
        names::DISC_ROTATING,
        names::ARM_LINKS,
        names::ARM_TOOL,
        names::ARM_MARKS,
        names::PART_TRUE_POSE,
        names::PART_TRUE_FEATURES,
    ] {
        assert!(rows_of(moving) > 1_000, "{moving}: {rows:?}");
        assert!(
            timelines_of(moving).contains(names::SIM_TIME),
            "{moving}: {timelines:?}"
        );
    }
    assert!(rows_of(names::CAMERA) > 0, "{rows:?}");
    // Frames with their labels, on both timelines.
    let images = rows_of(names::CAMERA_IMAGE);
    assert!(images >= 100, "{images} images: {rows:?}");
    assert_eq!(rows_of(names::CAMERA_LABELS), images, "{rows:?}");
    assert!(rows_of(names::CAMERA_RECEIVED) > 0, "{rows:?}");
    // (and the SDK's own `log_time`, the wall clock)
    let image_timelines = timelines_of(names::CAMERA_IMAGE);
    for timeline in [names::FRAME, names::SIM_TIME] {
        assert!(image_timelines.contains(timeline), "{image_timelines:?}");
    }
    // The controller's phases up to Done, its estimate against the truth.
    assert!(rows_of(names::PHASES) >= 5, "{rows:?}");
    for estimated in [
        names::PART_ESTIMATE,
        names::PART_ESTIMATE_POSE,
        names::PART_ERROR_MM,
        names::PART_SIGMA_MM,
        names::PART_YAW_ERROR_DEG,
        names::TOOL_REFERENCE,
    ] {
        assert!(rows_of(estimated) > 10, "{estimated}: {rows:?}");
    }
    eprintln!("{rows:#?}");
}
