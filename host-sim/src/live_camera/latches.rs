//! What a camera alone cannot give: the conveyor's angle and the gripper
//! marks' base-frame positions latched at each trigger. They come from a
//! CSV the cell's controller (or any encoder logger) writes, one row per
//! trigger in trigger order, columns by name as in `frames.csv`:
//! `conveyor_angle_rad` and `e{i}_base_{x,y,z}_m` required,
//! `trigger_id` and `capture_time_us` optional (else the frame's count and
//! the host's clock). The k-th frame grabbed takes the k-th row; the angle
//! is taken relative to the first row's (a recording starts at 0).

use anyhow::{bail, Context, Result};

/// One trigger's latched values.
#[derive(Debug, Clone, PartialEq)]
pub struct Latch {
    pub trigger_id: Option<u64>,
    pub capture_time_us: Option<u64>,
    pub conveyor_angle_rad: f64,
    pub effector_base_m: Vec<[f64; 3]>,
}

/// Parses a latches CSV for `effector_marks` gripper marks.
pub fn parse_latches(text: &str, effector_marks: usize) -> Result<Vec<Latch>> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')));
    let Some((_, header)) = lines.next() else {
        bail!("line 1: the file is empty");
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let column = |name: &str| names.iter().position(|n| *n == name);
    let required =
        |name: &str| column(name).with_context(|| format!("line 1: column {name} is missing"));
    let angle = required("conveyor_angle_rad")?;
    let marks = (0..effector_marks)
        .map(|i| {
            Ok([
                required(&format!("e{i}_base_x_m"))?,
                required(&format!("e{i}_base_y_m"))?,
                required(&format!("e{i}_base_z_m"))?,
            ])
        })
        .collect::<Result<Vec<[usize; 3]>>>()?;
    let (id, time) = (column("trigger_id"), column("capture_time_us"));
    let mut latches = Vec::new();
    for (line, text) in lines {
        if text.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        let field = |k: usize| -> Result<&str> {
            fields
                .get(k)
                .copied()
                .filter(|f| !f.is_empty())
                .with_context(|| format!("line {line}: {} is missing", names[k]))
        };
        let number = |k: usize| -> Result<f64> {
            let f = field(k)?;
            match f.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => bail!("line {line}: {} is not a finite number: {f:?}", names[k]),
            }
        };
        let integer = |k: Option<usize>| -> Result<Option<u64>> {
            k.map(|k| {
                let f = field(k)?;
                f.parse::<u64>()
                    .with_context(|| format!("line {line}: {} is not an integer: {f:?}", names[k]))
            })
            .transpose()
        };
        latches.push(Latch {
            trigger_id: integer(id)?,
            capture_time_us: integer(time)?,
            conveyor_angle_rad: number(angle)?,
            effector_base_m: marks
                .iter()
                .map(|m| Ok([number(m[0])?, number(m[1])?, number(m[2])?]))
                .collect::<Result<_>>()?,
        });
    }
    Ok(latches)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_found_by_name_and_the_optional_ones_may_be_absent() {
        let text = "e0_base_x_m,conveyor_angle_rad,e0_base_y_m,e0_base_z_m,extra\n\
                    0.5,0.25,-0.1,0.6,x\n\
                    \n\
                    0.51,0.35,-0.1,0.6,y\n";
        let latches = parse_latches(text, 1).unwrap();
        assert_eq!(latches.len(), 2);
        assert_eq!(latches[1].conveyor_angle_rad, 0.35);
        assert_eq!(latches[0].effector_base_m, vec![[0.5, -0.1, 0.6]]);
        assert_eq!(
            (latches[0].trigger_id, latches[0].capture_time_us),
            (None, None)
        );
        let timed = parse_latches(
            "trigger_id,capture_time_us,conveyor_angle_rad\n4,1000,0\n",
            0,
        )
        .unwrap();
        assert_eq!(
            (timed[0].trigger_id, timed[0].capture_time_us),
            (Some(4), Some(1000))
        );
    }

    #[test]
    fn a_bad_latch_file_says_where() {
        let missing = parse_latches("conveyor_angle_rad\n0\n", 1).unwrap_err();
        assert!(missing.to_string().contains("e0_base_x_m"), "{missing}");
        let nan = parse_latches("conveyor_angle_rad\n0\nNaN\n", 0).unwrap_err();
        assert!(nan.to_string().contains("line 3"), "{nan}");
        let empty = parse_latches("conveyor_angle_rad\n,\n", 0).unwrap_err();
        assert!(empty.to_string().contains("line 2"), "{empty}");
        assert!(parse_latches("", 0).is_err());
    }
}
