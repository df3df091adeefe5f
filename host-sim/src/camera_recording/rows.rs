//! `frames.csv`: one row per frame in trigger order. Columns are found by
//! name, extra ones ignored; a malformed row is an error naming its line and
//! column, and so are trigger ids that do not increase, capture times that go
//! back, and a first angle other than 0.

use super::error::RecordingError;

/// One row: what the cell latched at a trigger, and the frame's file.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRow {
    /// 1-based line of `frames.csv`.
    pub line: usize,
    pub trigger_id: u64,
    /// Middle of the exposure, us.
    pub capture_time_us: u64,
    /// `theta` at the middle of the exposure, unwrapped, 0 at the first frame.
    pub conveyor_angle_rad: f64,
    /// Path of the image relative to the recording's folder.
    pub image: String,
    /// Each effector mark's centre in the base frame (joint encoders and
    /// kinematics), m.
    pub effector_base_m: Vec<[f64; 3]>,
}

/// The column names of a recording with `effector_marks` gripper marks.
pub fn column_names(effector_marks: usize) -> Vec<String> {
    let mut names: Vec<String> = [
        "trigger_id",
        "capture_time_us",
        "conveyor_angle_rad",
        "image",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    for i in 0..effector_marks {
        for axis in ["x", "y", "z"] {
            names.push(format!("e{i}_base_{axis}_m"));
        }
    }
    names
}

/// Parses the whole of `frames.csv`.
pub fn parse_rows(text: &str, effector_marks: usize) -> Result<Vec<FrameRow>, RecordingError> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')));
    let (_, header) = lines
        .next()
        .ok_or_else(|| RecordingError::row(1, "(header)", "the file is empty"))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let wanted = column_names(effector_marks);
    let mut index = Vec::with_capacity(wanted.len());
    for name in &wanted {
        let at = names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| RecordingError::row(1, name, "missing from the header row"))?;
        index.push(at);
    }
    let mut rows: Vec<FrameRow> = Vec::new();
    for (line, text) in lines {
        if text.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        let field = |k: usize| -> Result<&str, RecordingError> {
            let name = &wanted[k];
            fields
                .get(index[k])
                .copied()
                .filter(|f| !f.is_empty())
                .ok_or_else(|| RecordingError::row(line, name, "missing field"))
        };
        let integer = |k: usize| -> Result<u64, RecordingError> {
            let f = field(k)?;
            f.parse::<u64>().map_err(|_| {
                RecordingError::row(
                    line,
                    &wanted[k],
                    format!("not a non-negative integer: {f:?}"),
                )
            })
        };
        let number = |k: usize| -> Result<f64, RecordingError> {
            let f = field(k)?;
            match f.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                Ok(_) => Err(RecordingError::row(
                    line,
                    &wanted[k],
                    format!("not finite: {f:?}"),
                )),
                Err(_) => Err(RecordingError::row(
                    line,
                    &wanted[k],
                    format!("not a number: {f:?}"),
                )),
            }
        };
        let row = FrameRow {
            line,
            trigger_id: integer(0)?,
            capture_time_us: integer(1)?,
            conveyor_angle_rad: number(2)?,
            image: field(3)?.to_string(),
            effector_base_m: (0..effector_marks)
                .map(|i| Ok([number(4 + 3 * i)?, number(5 + 3 * i)?, number(6 + 3 * i)?]))
                .collect::<Result<_, RecordingError>>()?,
        };
        check_follows(rows.last(), &row)?;
        rows.push(row);
    }
    Ok(rows)
}

/// Checks that `row` may follow `previous` (or open the table): finite
/// numbers, a first angle of exactly 0, increasing trigger ids and capture
/// times that do not go back.
pub fn check_follows(previous: Option<&FrameRow>, row: &FrameRow) -> Result<(), RecordingError> {
    let line = row.line;
    if !row.conveyor_angle_rad.is_finite() {
        return Err(RecordingError::row(
            line,
            "conveyor_angle_rad",
            "not finite",
        ));
    }
    for (i, p) in row.effector_base_m.iter().enumerate() {
        for (axis, x) in ["x", "y", "z"].iter().zip(p) {
            if !x.is_finite() {
                return Err(RecordingError::row(
                    line,
                    &format!("e{i}_base_{axis}_m"),
                    "not finite",
                ));
            }
        }
    }
    match previous {
        None if row.conveyor_angle_rad != 0.0 => {
            return Err(RecordingError::row(
                line,
                "conveyor_angle_rad",
                format!(
                    "must be exactly 0 at the first frame, got {}",
                    row.conveyor_angle_rad
                ),
            ))
        }
        Some(previous) if row.trigger_id <= previous.trigger_id => {
            return Err(RecordingError::row(
                line,
                "trigger_id",
                format!(
                    "{} does not increase (line {} has {})",
                    row.trigger_id, previous.line, previous.trigger_id
                ),
            ))
        }
        Some(previous) if row.capture_time_us < previous.capture_time_us => {
            return Err(RecordingError::row(
                line,
                "capture_time_us",
                format!(
                    "{} goes back (line {} has {})",
                    row.capture_time_us, previous.line, previous.capture_time_us
                ),
            ))
        }
        _ => {}
    }
    Ok(())
}

/// One row as CSV text in [`column_names`]' order (with its newline).
pub fn format_row(row: &FrameRow) -> String {
    let mut fields = vec![
        row.trigger_id.to_string(),
        row.capture_time_us.to_string(),
        format!("{:?}", row.conveyor_angle_rad),
        row.image.clone(),
    ];
    for p in &row.effector_base_m {
        fields.extend(p.iter().map(|x| format!("{x:?}")));
    }
    let mut text = fields.join(",");
    text.push('\n');
    text
}
