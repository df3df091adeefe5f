//! The shipped recording read end to end, the writer's round trip, and every
//! bad input the contract names.

use std::fs;
use std::path::{Path, PathBuf};

use super::*;
use crate::front_end;

fn shipped() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/recording-small")
}

/// A copy of the shipped recording to spoil.
fn copy_of_shipped() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let from = shipped();
    fs::create_dir_all(dir.path().join("images")).unwrap();
    for name in [HEADER_FILE, FRAMES_FILE] {
        fs::copy(from.join(name), dir.path().join(name)).unwrap();
    }
    for entry in fs::read_dir(from.join("images")).unwrap() {
        let entry = entry.unwrap();
        fs::copy(
            entry.path(),
            dir.path().join("images").join(entry.file_name()),
        )
        .unwrap();
    }
    dir
}

fn replace_in(path: &Path, from: &str, to: &str) {
    let text = fs::read_to_string(path).unwrap();
    assert!(text.contains(from), "{from:?} not in {}", path.display());
    fs::write(path, text.replacen(from, to, 1)).unwrap();
}

#[test]
fn the_shipped_recording_reads_end_to_end() {
    let recording = Recording::open(&shipped()).unwrap();
    assert_eq!(recording.rows.len(), 8);
    assert_eq!(recording.header.camera.width, 256);
    assert_eq!(recording.header.effector.len(), 2);
    assert_eq!(recording.rows[0].conveyor_angle_rad, 0.0);
    let outcome = front_end::run(&recording, false).unwrap();
    assert_eq!(outcome.log.frames.len(), 8);
    // Every frame shows the disc centre, the reference, three features and
    // a gripper mark: the detector finds at least five blobs.
    for frame in &outcome.frames {
        assert!(frame.blobs.len() >= 5, "{frame:?}");
    }
    // What the front end writes is a log the reader takes back.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("log.jsonl");
    crate::log::write_log_file(&path, &outcome.log).unwrap();
    assert_eq!(crate::log::read_log_file(&path).unwrap(), outcome.log);
}

#[test]
fn the_writer_round_trips() {
    let recording = Recording::open(&shipped()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut writer = RecordingWriter::create(dir.path(), &recording.header).unwrap();
    for row in &recording.rows {
        writer
            .push(row.clone(), &recording.image(row).unwrap())
            .unwrap();
    }
    writer.finish().unwrap();
    let back = Recording::open(dir.path()).unwrap();
    assert_eq!(back.header, recording.header);
    for (a, b) in back.rows.iter().zip(&recording.rows) {
        assert_eq!(
            (
                a.trigger_id,
                a.capture_time_us,
                a.conveyor_angle_rad,
                &a.effector_base_m
            ),
            (
                b.trigger_id,
                b.capture_time_us,
                b.conveyor_angle_rad,
                &b.effector_base_m
            )
        );
        assert_eq!(back.image(a).unwrap(), recording.image(b).unwrap());
    }
    // A row that would not read back is refused.
    let mut writer = RecordingWriter::create(dir.path(), &recording.header).unwrap();
    let mut row = recording.rows[1].clone();
    assert!(
        writer.push(row.clone(), &[0; 256 * 256]).is_err(),
        "first angle not 0"
    );
    row.conveyor_angle_rad = 0.0;
    writer.push(row.clone(), &[0; 256 * 256]).unwrap();
    assert!(
        writer.push(row, &[0; 256 * 256]).is_err(),
        "same trigger id"
    );
}

#[test]
fn unknown_keys_and_extra_columns_are_ignored() {
    let dir = copy_of_shipped();
    replace_in(&dir.path().join(HEADER_FILE), "{", "{\"site\":\"lab 3\",");
    let csv = dir.path().join(FRAMES_FILE);
    let text = fs::read_to_string(&csv).unwrap();
    let widened: String = text.lines().map(|l| format!("{l},extra\n")).collect();
    fs::write(&csv, widened).unwrap();
    let recording = Recording::open(dir.path()).unwrap();
    assert_eq!(recording.rows.len(), 8);
}

fn open_error(dir: &Path) -> String {
    Recording::open(dir).unwrap_err().to_string()
}

#[test]
fn a_bad_header_names_its_key() {
    let cases = [
        ("\"version\":1", "\"version\":2", "`version`"),
        ("\"f_px\":", "\"f_pixels\":", "`camera.f_px`: missing"),
        (
            "\"part_feature_count\":3",
            "\"part_feature_count\":\"3\"",
            "`part_feature_count`",
        ),
        (
            "\"polarity\":\"bright\"",
            "\"polarity\":\"shiny\"",
            "polarity",
        ),
    ];
    for (from, to, expected) in cases {
        let dir = copy_of_shipped();
        replace_in(&dir.path().join(HEADER_FILE), from, to);
        let error = open_error(dir.path());
        assert!(error.contains(expected), "{error}");
    }
}

#[test]
fn a_bad_row_names_its_line_and_column() {
    let header = "trigger_id,capture_time_us,conveyor_angle_rad,image,e0_base_x_m,e0_base_y_m,e0_base_z_m,e1_base_x_m,e1_base_y_m,e1_base_z_m\n";
    let good = "0,0,0.0,images/000000.png,0.5,-0.1,0.6,0.6,-0.1,0.6\n";
    let cases = [
        // A missing column.
        (header.replace(",e1_base_z_m", ""), good.to_string(), "line 1, column `e1_base_z_m`"),
        // NaN.
        (header.to_string(), format!("{good}1,200000,NaN,images/000001.png,0.5,-0.1,0.6,0.6,-0.1,0.6\n"), "line 3, column `conveyor_angle_rad`: not finite"),
        // Not a number.
        (header.to_string(), format!("{good}1,200000,0.1,images/000001.png,0.5,x,0.6,0.6,-0.1,0.6\n"), "line 3, column `e0_base_y_m`: not a number"),
        // A missing field.
        (header.to_string(), format!("{good}1,200000,0.1,images/000001.png,0.5,-0.1\n"), "line 3, column `e0_base_z_m`: missing field"),
        // Trigger ids out of order.
        (header.to_string(), format!("{good}0,200000,0.1,images/000001.png,0.5,-0.1,0.6,0.6,-0.1,0.6\n"), "line 3, column `trigger_id`"),
        // Time going back.
        (header.to_string(), "5,900,0.0,images/000000.png,0.5,-0.1,0.6,0.6,-0.1,0.6\n6,800,0.1,images/000001.png,0.5,-0.1,0.6,0.6,-0.1,0.6\n".to_string(), "line 3, column `capture_time_us`"),
        // A first angle other than 0.
        (header.to_string(), "0,0,0.5,images/000000.png,0.5,-0.1,0.6,0.6,-0.1,0.6\n".to_string(), "line 2, column `conveyor_angle_rad`"),
    ];
    for (head, body, expected) in cases {
        let dir = copy_of_shipped();
        fs::write(dir.path().join(FRAMES_FILE), format!("{head}{body}")).unwrap();
        let error = open_error(dir.path());
        assert!(error.contains(expected), "{error} (wanted {expected})");
    }
}

#[test]
fn bad_images_name_their_file_or_are_skipped_and_counted() {
    type Spoil = (&'static str, fn(&Path));
    let spoil: [Spoil; 4] = [
        ("truncated", |p| {
            let bytes = fs::read(p).unwrap();
            fs::write(p, &bytes[..bytes.len() / 2]).unwrap();
        }),
        ("corrupt", |p| {
            let mut bytes = fs::read(p).unwrap();
            for b in bytes.iter_mut().skip(60).take(400) {
                *b ^= 0x5a;
            }
            fs::write(p, bytes).unwrap();
        }),
        ("wrong size", |p| {
            png_io::write_gray_png(p, 100, 80, &[7; 8000]).unwrap()
        }),
        ("missing", |p| fs::remove_file(p).unwrap()),
    ];
    for (what, spoil) in spoil {
        let dir = copy_of_shipped();
        spoil(&dir.path().join("images/000003.png"));
        let recording = Recording::open(dir.path()).unwrap();
        let error = front_end::run(&recording, false).unwrap_err();
        let text = format!("{error:#}");
        assert!(text.contains("images/000003.png"), "{what}: {text}");
        if what == "wrong size" {
            assert!(text.contains("100 x 80"), "{text}");
        }
        let skipped = front_end::run(&recording, true).unwrap();
        assert_eq!(skipped.skipped_images, 1, "{what}");
        assert_eq!(skipped.log.frames.len(), 7, "{what}");
    }
}
