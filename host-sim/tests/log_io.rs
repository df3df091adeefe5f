//! Observation-log reader and writer: every malformed case is refused with an
//! error naming the line and the field; whatever is written reads back exactly.

use std::io::Cursor;

use host_sim::log::{read_log, write_log, LogError, LogReader, LogWriter, DEFAULT_MAX_LINE_BYTES};
use host_sim::recording::simulate;
use host_sim::scenario::Scenario;

const HEADER: &str = r#"{"type":"header","version":1,"camera":{"width":256,"height":256,"f_px":290.0,"cx":127.5,"cy":127.5},"reference_radius_m":0.40,"part_feature_count":3}"#;

fn frame(t_s: f64) -> String {
    format!(
        r#"{{"type":"frame","t_s":{t_s},"conveyor_angle_rad":0.0982,"center_px":[131.2,120.7],"reference_px":[171.9,118.3],"part_px":[[150.1,99.3],[158.0,97.2],[151.4,90.0]],"effector_px":null,"effector_base_m":null}}"#
    )
}

/// A valid log of a header and four frames, as lines.
fn valid_lines() -> Vec<String> {
    let mut lines = vec![HEADER.to_string()];
    lines.extend((0..4).map(|i| frame(f64::from(i) * 0.125)));
    lines
}

fn parse(lines: &[String]) -> Result<host_sim::log::ObservationLog, LogError> {
    read_log(Cursor::new(lines.join("\n")))
}

/// Replaces `from` by `to` in line `line` (1-based) of a valid log and parses it.
fn parse_with_edit(
    line: usize,
    from: &str,
    to: &str,
) -> Result<host_sim::log::ObservationLog, LogError> {
    let mut lines = valid_lines();
    let target = &mut lines[line - 1];
    assert!(
        target.contains(from),
        "test setup: {from} not in line {line}"
    );
    *target = target.replacen(from, to, 1);
    parse(&lines)
}

/// Asserts the parse failed on `line`, naming `field`, with a message containing `needle`.
fn assert_error(
    result: Result<host_sim::log::ObservationLog, LogError>,
    line: usize,
    field: Option<&str>,
    needle: &str,
) {
    let error = match result {
        Ok(_) => panic!("expected an error on line {line}, the log was accepted"),
        Err(e) => e,
    };
    let message = error.to_string();
    assert_eq!(error.line, line, "wrong line in: {message}");
    assert_eq!(error.field.as_deref(), field, "wrong field in: {message}");
    assert!(
        message.starts_with(&format!("line {line}: ")),
        "message: {message}"
    );
    if let Some(field) = field {
        assert!(
            message.contains(&format!("field \"{field}\"")),
            "message: {message}"
        );
    }
    assert!(
        message.contains(needle),
        "message lacks {needle:?}: {message}"
    );
}

#[test]
fn valid_log_parses_with_unknown_keys_ignored_and_trailing_blank_line() {
    let mut lines = valid_lines();
    lines[2] = lines[2].replacen(
        "\"t_s\"",
        "\"exposure_us\":900,\"extra\":{\"a\":[1]},\"t_s\"",
        1,
    );
    lines[0] = lines[0].replacen("\"version\"", "\"vendor\":\"x\",\"version\"", 1);
    lines.push(String::new());
    let log = parse(&lines).expect("valid log");
    assert_eq!(log.frames.len(), 4);
    assert_eq!(log.header.part_feature_count, 3);
    assert_eq!(log.frames[1].reference_px, Some([171.9, 118.3]));
    assert_eq!(log.frames[3].t_s, 0.375);
}

#[test]
fn header_errors_name_line_one_and_the_field() {
    assert_error(
        parse_with_edit(1, "\"version\":1", "\"version\":2"),
        1,
        Some("version"),
        "unsupported log version 2",
    );
    assert_error(
        parse_with_edit(1, "\"version\":1", "\"version\":\"1\""),
        1,
        Some("version"),
        "expected a non-negative integer",
    );
    assert_error(
        parse_with_edit(1, "\"reference_radius_m\":0.40,", ""),
        1,
        Some("reference_radius_m"),
        "required key is missing",
    );
    assert_error(
        parse_with_edit(
            1,
            "\"reference_radius_m\":0.40",
            "\"reference_radius_m\":-0.4",
        ),
        1,
        Some("reference_radius_m"),
        "greater than 0",
    );
    assert_error(
        parse_with_edit(1, "\"f_px\":290.0", "\"f_px\":\"290\""),
        1,
        Some("camera.f_px"),
        "expected a finite number, got a string \"290\"",
    );
    assert_error(
        parse_with_edit(1, "\"width\":256", "\"width\":0"),
        1,
        Some("camera.width"),
        "between 1 and",
    );
    assert_error(
        parse_with_edit(1, "\"cy\":127.5", "\"cy\":null"),
        1,
        Some("camera.cy"),
        "got null",
    );
    assert_error(
        parse_with_edit(1, "\"part_feature_count\":3", "\"part_feature_count\":1"),
        1,
        Some("part_feature_count"),
        "from 2 to 8",
    );
    assert_error(
        parse_with_edit(1, "\"part_feature_count\":3", "\"part_feature_count\":9"),
        1,
        Some("part_feature_count"),
        "from 2 to 8",
    );
    assert_error(
        parse_with_edit(1, "\"type\":\"header\"", "\"type\":\"frame\""),
        1,
        Some("type"),
        "expected record type \"header\"",
    );
    assert_error(
        parse_with_edit(1, "\"camera\":{", "\"camera\":[{"),
        1,
        Some("camera[1]"),
        "not valid JSON",
    );
}

#[test]
fn frame_errors_name_the_line_and_the_field() {
    assert_error(
        parse_with_edit(
            4,
            "\"reference_px\":[171.9,118.3]",
            "\"reference_px\":[171.9,\"x\"]",
        ),
        4,
        Some("reference_px"),
        "expected [u, v] of 2 finite numbers, got an array [171.9,\"x\"]",
    );
    assert_error(
        parse_with_edit(
            3,
            "\"reference_px\":[171.9,118.3]",
            "\"reference_px\":[171.9,118.3,1.0]",
        ),
        3,
        Some("reference_px"),
        "expected [u, v] of 2 finite numbers",
    );
    assert_error(
        parse_with_edit(2, "\"center_px\":[131.2,120.7]", "\"center_px\":131.2"),
        2,
        Some("center_px"),
        "expected [u, v]",
    );
    assert_error(
        parse_with_edit(5, "\"t_s\":0.375,", ""),
        5,
        Some("t_s"),
        "required key is missing",
    );
    assert_error(
        parse_with_edit(3, "\"t_s\":0.125", "\"t_s\":true"),
        3,
        Some("t_s"),
        "expected a finite number, got a boolean true",
    );
    assert_error(
        parse_with_edit(4, "\"t_s\":0.25", "\"t_s\":0.1"),
        4,
        Some("t_s"),
        "before the previous frame's t_s 0.125",
    );
    assert_error(
        parse_with_edit(
            2,
            "\"conveyor_angle_rad\":0.0982",
            "\"conveyor_angle_rad\":null",
        ),
        2,
        Some("conveyor_angle_rad"),
        "expected a finite number, got null",
    );
    assert_error(
        parse_with_edit(3, ",\"effector_px\":null", ""),
        3,
        Some("effector_px"),
        "required key is missing",
    );
    assert_error(
        parse_with_edit(
            3,
            "[[150.1,99.3],[158.0,97.2],[151.4,90.0]]",
            "[[150.1,99.3],[158.0,97.2]]",
        ),
        3,
        Some("part_px"),
        "expected 3 feature points (header part_feature_count), got 2",
    );
    assert_error(
        parse_with_edit(5, "[158.0,97.2]", "[158.0]"),
        5,
        Some("part_px[1]"),
        "expected [u, v] of 2 finite numbers, got an array [158.0]",
    );
    assert_error(
        parse_with_edit(2, "\"part_px\":[[", "\"part_px\":{\"a\":[["),
        2,
        Some("part_px"),
        "not valid JSON",
    );
    assert_error(
        parse_with_edit(
            2,
            "\"part_px\":[[150.1,99.3],[158.0,97.2],[151.4,90.0]]",
            "\"part_px\":\"all\"",
        ),
        2,
        Some("part_px"),
        "null or a list of [u, v] points",
    );
    assert_error(
        parse_with_edit(4, "\"type\":\"frame\"", "\"type\":\"header\""),
        4,
        Some("type"),
        "expected record type \"frame\"",
    );
    assert_error(
        parse_with_edit(4, "\"type\":\"frame\",", ""),
        4,
        Some("type"),
        "required key is missing",
    );
}

#[test]
fn effector_pairing_and_shape_errors() {
    assert_error(
        parse_with_edit(
            3,
            "\"effector_px\":null",
            "\"effector_px\":[[10.0,20.0],[30.0,40.0]]",
        ),
        3,
        Some("effector_base_m"),
        "effector_px present, effector_base_m null",
    );
    assert_error(
        parse_with_edit(
            4,
            "\"effector_base_m\":null",
            "\"effector_base_m\":[[0.1,0.2,0.3],[0.2,0.2,0.3]]",
        ),
        4,
        Some("effector_px"),
        "effector_px null, effector_base_m present",
    );
    let both =
        "\"effector_px\":[[10.0,20.0],[30.0,40.0]],\"effector_base_m\":[[0.1,0.2,0.3],[0.2,0.2]]}";
    assert_error(
        parse_with_edit(2, "\"effector_px\":null,\"effector_base_m\":null}", both),
        2,
        Some("effector_base_m[1]"),
        "expected [x, y, z] of 3 finite numbers",
    );
    let three = "\"effector_px\":[[10.0,20.0],[30.0,40.0],[1.0,1.0]],\"effector_base_m\":[[0.1,0.2,0.3],[0.2,0.2,0.3]]}";
    assert_error(
        parse_with_edit(2, "\"effector_px\":null,\"effector_base_m\":null}", three),
        2,
        Some("effector_px"),
        "expected 2 feature points",
    );
    let good = "\"effector_px\":[[10.0,20.0],[30.0,40.0]],\"effector_base_m\":[[0.1,0.2,0.3],[0.2,0.2,0.3]]}";
    let log = parse_with_edit(2, "\"effector_px\":null,\"effector_base_m\":null}", good)
        .expect("valid sighting");
    let sighting = log.frames[0].effector.expect("sighting");
    assert_eq!(sighting.px, [[10.0, 20.0], [30.0, 40.0]]);
    assert_eq!(sighting.base_m[1], [0.2, 0.2, 0.3]);
}

#[test]
fn non_finite_and_malformed_lines_name_the_line() {
    // JSON has no NaN or infinity, but a literal can overflow f64.
    assert_error(
        parse_with_edit(3, "\"t_s\":0.125", "\"t_s\":1e999"),
        3,
        Some("t_s"),
        "expected a finite number, got a number 1e999 (outside the f64 range)",
    );
    assert_error(
        parse_with_edit(2, "[158.0,97.2]", "[158.0,1e999]"),
        2,
        Some("part_px[1][1]"),
        "expected a finite number, got a number 1e999 (outside the f64 range)",
    );
    assert_error(
        parse_with_edit(4, "[171.9,118.3]", "[-1e400,118.3]"),
        4,
        Some("reference_px[0]"),
        "expected a finite number, got a number -1e400 (outside the f64 range)",
    );
    assert_error(
        parse_with_edit(1, "\"f_px\":290.0", "\"f_px\":2e308"),
        1,
        Some("camera.f_px"),
        "expected a finite number, got a number 2e308 (outside the f64 range)",
    );
    // In an unknown key an overflowing number is as harmless as any other value.
    let log = parse_with_edit(3, "\"t_s\"", "\"gain\":1e999,\"t_s\"").expect("unknown key ignored");
    assert_eq!(log.frames.len(), 4);
    assert_error(
        parse_with_edit(3, "\"t_s\":0.125", "\"t_s\":NaN"),
        3,
        Some("t_s"),
        "not valid JSON",
    );
    let mut lines = valid_lines();
    lines[2] = "[1,2,3]".to_string();
    assert_error(
        parse(&lines),
        3,
        None,
        "expected a JSON object, got an array [1,2,3]",
    );
    lines[2] = "{\"type\":\"frame\"".to_string();
    assert_error(
        parse(&lines),
        3,
        Some("type"),
        "not valid JSON: EOF while parsing an object at column 15",
    );
    let bytes = [HEADER.as_bytes(), b"\n\xff\xfe\n"].concat();
    let error = read_log(Cursor::new(bytes)).expect_err("invalid UTF-8");
    assert_eq!(error.line, 2);
    assert!(
        error.to_string().contains("invalid UTF-8 at column 1"),
        "{error}"
    );
    assert_error(read_log(Cursor::new("")), 1, None, "the log is empty");
}

#[test]
fn overlong_line_is_refused_without_reading_it_whole() {
    const { assert!(DEFAULT_MAX_LINE_BYTES >= 1 << 20 && DEFAULT_MAX_LINE_BYTES <= 16 << 20) };
    let padding = "x".repeat(10_000);
    let long_frame = frame(0.5).replacen("\"t_s\"", &format!("\"junk\":\"{padding}\",\"t_s\""), 1);
    let text = [HEADER.to_string(), frame(0.0), long_frame, frame(0.75)].join("\n");
    let mut reader =
        LogReader::with_max_line_bytes(Cursor::new(text.clone()), 4096).expect("header fits");
    assert!(reader.next().is_some_and(|f| f.is_ok()));
    let error = reader.next().expect("an item").expect_err("line too long");
    assert_eq!(error.line, 3);
    assert!(
        error
            .to_string()
            .contains("longer than the limit of 4096 bytes"),
        "{error}"
    );
    assert!(reader.next().is_none(), "the reader stops after an error");
    // With the default cap the same line is fine (unknown key ignored).
    assert_eq!(
        read_log(Cursor::new(text))
            .expect("default cap")
            .frames
            .len(),
        3
    );
    // A line exactly at the cap is accepted, one byte more is not.
    let exact = HEADER.len();
    assert!(LogReader::with_max_line_bytes(Cursor::new(HEADER), exact).is_ok());
    let error = LogReader::with_max_line_bytes(Cursor::new(HEADER), exact - 1)
        .err()
        .expect("too long");
    assert_eq!(error.line, 1);
}

#[test]
fn crlf_line_endings_are_accepted() {
    let text = valid_lines().join("\r\n");
    assert_eq!(
        read_log(Cursor::new(text)).expect("CRLF log").frames.len(),
        4
    );
}

#[test]
fn synthetic_logs_round_trip_exactly() {
    for (name, seed) in [("noisy", 11), ("non-planar", 12), ("noise-free", 13)] {
        let scenario = Scenario::named(name).expect("scenario");
        let run = simulate(&scenario, seed).expect("workcell");
        let bytes = write_log(Vec::new(), &run.log).expect("write");
        let text = String::from_utf8(bytes.clone()).expect("utf-8");
        assert_eq!(text.lines().count(), run.log.frames.len() + 1);
        assert!(text.starts_with("{\"type\":\"header\",\"version\":1,"));
        let back = read_log(Cursor::new(bytes)).expect("read back");
        assert_eq!(back.header, run.log.header, "scenario {name}");
        assert_eq!(back.frames.len(), run.log.frames.len());
        for (line, (read, written)) in back.frames.iter().zip(&run.log.frames).enumerate() {
            assert_eq!(read, written, "scenario {name}, frame line {}", line + 2);
        }
    }
}

#[test]
fn writer_refuses_what_the_reader_would_refuse_and_writes_nothing_then() {
    let run = simulate(&Scenario::paper(), 5).expect("workcell");
    let mut writer = LogWriter::new(Vec::new(), &run.log.header).expect("header");
    let first = run.log.frames[0].clone();
    let second = run.log.frames[1].clone();
    writer.write_frame(&second).expect("frame");

    let earlier = LogWriter::new(Vec::new(), &run.log.header).map(|mut w| {
        w.write_frame(&second).expect("frame");
        w.write_frame(&first)
    });
    let error = earlier.expect("header").expect_err("time going backwards");
    assert_eq!(error.line, 3);
    assert_eq!(error.field.as_deref(), Some("t_s"));

    let mut nan_frame = second.clone();
    nan_frame.center_px = Some([f64::NAN, 3.0]);
    let error = writer.write_frame(&nan_frame).expect_err("NaN refused");
    assert_eq!(error.field.as_deref(), Some("center_px"));
    assert_eq!(error.line, 3);

    let mut bad_header = run.log.header;
    bad_header.reference_radius_m = f64::INFINITY;
    let error = LogWriter::new(Vec::new(), &bad_header)
        .err()
        .expect("inf refused");
    assert_eq!(error.field.as_deref(), Some("reference_radius_m"));

    let bytes = writer.finish().expect("flush");
    let back = read_log(Cursor::new(bytes)).expect("what was written is valid");
    assert_eq!(back.frames, vec![second]);
}

/// The project's additions (the header's `disc_radius_m`, a frame's `rim`):
/// read back exactly, and a bad one is refused naming its field.
#[test]
fn the_rim_and_the_disc_radius_read_back_and_a_bad_rim_is_named() {
    let rim = r#","rim":{"centre_px":[128.25,121.5],"semi_axes_px":[47.125,44.5],"angle_rad":0.25,"sigma_px":0.0065}"#;
    let mut lines = valid_lines();
    lines[0] = HEADER.replace(
        "\"part_feature_count\":3",
        "\"part_feature_count\":3,\"disc_radius_m\":0.45",
    );
    lines[1] = format!("{}{rim}}}", frame(0.0).trim_end_matches('}'));
    let log = parse(&lines).unwrap();
    assert_eq!(log.header.disc_radius_m, Some(0.45));
    let read = log.frames[0].rim.unwrap();
    assert_eq!(read.centre_px, [128.25, 121.5]);
    assert_eq!(read.semi_axes_px, [47.125, 44.5]);
    assert_eq!((read.angle_rad, read.sigma_px), (0.25, 0.0065));
    assert!(log.frames[1].rim.is_none());
    // Written and read again: the same.
    let written = write_log(Vec::new(), &log).unwrap();
    let again = read_log(Cursor::new(written)).unwrap();
    assert_eq!(again.header, log.header);
    assert_eq!(again.frames, log.frames);

    let with = |edit: &str| {
        let mut bad = lines.clone();
        bad[1] = format!("{}{edit}}}", frame(0.0).trim_end_matches('}'));
        parse(&bad)
    };
    assert_error(
        with(
            r#","rim":{"centre_px":[128.0,121.0],"semi_axes_px":[-1.0,44.0],"angle_rad":0.0,"sigma_px":0.01}"#,
        ),
        2,
        Some("rim.semi_axes_px"),
        "greater than 0",
    );
    assert_error(
        with(r#","rim":{"centre_px":[128.0,121.0],"semi_axes_px":[40.0,44.0],"angle_rad":0.0}"#),
        2,
        Some("rim.sigma_px"),
        "is missing",
    );
    assert_error(with(r#","rim":7"#), 2, Some("rim"), "object");
    let mut bad = valid_lines();
    bad[0] = HEADER.replace(
        "\"part_feature_count\":3",
        "\"part_feature_count\":3,\"disc_radius_m\":-0.45",
    );
    assert_error(parse(&bad), 1, Some("disc_radius_m"), "greater than 0");
}
