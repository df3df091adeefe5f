//! Every output of one pick written into its own folder: the CSV files
//! ([`super::csv`]) and the PNG figures ([`super::plots`]).

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::csv::{calibration_csv, grasp_csv, phases_csv, timeseries_csv};
use super::plots;
use super::record::PickRun;

/// Writes every output of `run` into `dir/<experiment>/`: `timeseries.csv`,
/// `phases.csv`, `calibration.csv`, `grasp.csv` and the four PNG figures of
/// [`plots::write_run_plots`]. Returns the paths written, in that order.
pub fn write_run_outputs(run: &PickRun, dir: &Path) -> Result<Vec<PathBuf>> {
    let run_dir = dir.join(directory_name(&run.experiment));
    fs::create_dir_all(&run_dir)
        .with_context(|| format!("creating the output folder {}", run_dir.display()))?;
    let mut written = Vec::new();
    for (name, text) in [
        ("timeseries.csv", timeseries_csv(&run.records)),
        ("phases.csv", phases_csv(run)),
        ("calibration.csv", calibration_csv(&run.calibrations)),
        ("grasp.csv", grasp_csv(run)),
    ] {
        let path = run_dir.join(name);
        fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    written.extend(plots::write_run_plots(run, &run_dir)?);
    Ok(written)
}

/// A folder name from an experiment name: anything but ASCII letters, digits,
/// `-` and `_` becomes `_` so that a name can never climb out of `dir`.
pub fn directory_name(experiment: &str) -> String {
    let cleaned: String = experiment
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if cleaned.is_empty() {
        "run".to_owned()
    } else {
        cleaned
    }
}

#[cfg(test)]
mod tests {
    use shared::protocol::PickPhase;

    use super::*;
    use crate::pick::csv::timeseries_header;
    use crate::pick::record::PickResult;
    use crate::pick::report::results_table;
    use crate::pick::synthetic::synthetic_run;

    fn lines(path: &Path) -> Vec<String> {
        fs::read_to_string(path)
            .expect("read csv")
            .lines()
            .map(str::to_owned)
            .collect()
    }

    /// Width and height from a PNG's IHDR chunk, after checking the signature.
    fn png_size(path: &Path) -> (u32, u32) {
        let bytes = fs::read(path).expect("read png");
        assert_eq!(
            bytes.get(..8),
            Some(&[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a][..]),
            "{} is not a PNG",
            path.display()
        );
        assert_eq!(bytes.get(12..16), Some(&b"IHDR"[..]));
        let word = |at: usize| {
            let b: [u8; 4] = bytes.get(at..at + 4).expect("ihdr").try_into().expect("4");
            u32::from_be_bytes(b)
        };
        (word(16), word(20))
    }

    fn expected_files(dir: &Path) -> Vec<PathBuf> {
        [
            "timeseries.csv",
            "phases.csv",
            "calibration.csv",
            "grasp.csv",
            "part_pose.png",
            "part_pose_error.png",
            "tracking_error.png",
            "top_view.png",
        ]
        .iter()
        .map(|name| dir.join(name))
        .collect()
    }

    fn check_pngs(dir: &Path) {
        for (name, size) in [
            ("part_pose.png", plots::PART_POSE_SIZE),
            ("part_pose_error.png", plots::PART_POSE_ERROR_SIZE),
            ("tracking_error.png", plots::TRACKING_ERROR_SIZE),
            ("top_view.png", plots::TOP_VIEW_SIZE),
        ] {
            assert_eq!(png_size(&dir.join(name)), size, "{name}");
        }
    }

    #[test]
    fn writes_every_file_with_headers_and_row_counts() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let run = synthetic_run("experiment-1", 400);
        let written = write_run_outputs(&run, tmp.path()).expect("write outputs");
        let dir = tmp.path().join("experiment-1");
        assert_eq!(written, expected_files(&dir));
        assert!(written.iter().all(|p| p.is_file()));

        let timeseries = lines(&dir.join("timeseries.csv"));
        assert_eq!(timeseries.len(), 401);
        let header: Vec<&str> = timeseries[0].split(',').collect();
        assert_eq!(header.len(), 41);
        assert_eq!(header, timeseries_header());
        for column in [
            "t_s",
            "phase",
            "part_true_x_m",
            "part_est_yaw_rad",
            "q6_rad",
            "tau1_nm",
        ] {
            assert!(header.contains(&column), "{column} missing");
        }
        assert!(timeseries.iter().all(|row| row.split(',').count() == 41));
        // Before calibration the estimate is an empty cell; the phase is named.
        let first: Vec<&str> = timeseries[1].split(',').collect();
        assert_eq!(first[1], "SearchEffector");
        assert_eq!(first[6], "");
        let last: Vec<&str> = timeseries[400].split(',').collect();
        assert_eq!(last[1], "Return");
        let est_x: f64 = last[6].parse().expect("estimate x");
        assert!((est_x - run.records[399].part_est_base_m.expect("est")[0]).abs() < 1e-15);

        let phases = lines(&dir.join("phases.csv"));
        assert_eq!(phases.len(), run.phases.len() + 1);
        assert_eq!(phases[0], "phase,start_s,end_s,duration_s");
        assert!(phases[1].starts_with("SearchEffector,0,"));

        let calibration = lines(&dir.join("calibration.csv"));
        assert_eq!(calibration.len(), 1 + 19);
        assert_eq!(
            calibration[0],
            "calibration,t_s,quantity,estimate,truth,error,sigma"
        );
        let height: Vec<&str> = calibration[1].split(',').collect();
        assert_eq!(height[2], "camera_height_m");
        let error: f64 = height[5].parse().expect("height error");
        assert!((error - 0.02).abs() < 1e-6, "height error {error}");

        let grasp = lines(&dir.join("grasp.csv"));
        assert_eq!(grasp.len(), 2);
        assert!(grasp[0].starts_with("t_s,succeeded,position_error_x_m"));
        assert_eq!(grasp[0].split(',').count(), grasp[1].split(',').count());
        assert!(grasp[1].contains(",true,") && grasp[1].contains(",success,"));

        check_pngs(&dir);
    }

    #[test]
    fn an_empty_run_writes_without_panicking() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let mut run = synthetic_run("empty run", 0);
        run.phases.clear();
        run.calibrations.clear();
        run.grasp = None;
        run.result = PickResult::TimedOut(PickPhase::Idle);
        run.calibrated_after_s = None;
        let written = write_run_outputs(&run, tmp.path()).expect("write outputs");
        let dir = tmp.path().join("empty_run");
        assert_eq!(written, expected_files(&dir));
        assert_eq!(lines(&dir.join("timeseries.csv")).len(), 1);
        assert_eq!(lines(&dir.join("phases.csv")).len(), 1);
        assert_eq!(lines(&dir.join("calibration.csv")).len(), 1);
        assert_eq!(lines(&dir.join("grasp.csv")).len(), 1);
        check_pngs(&dir);
        let table = results_table(&[run]);
        assert!(table.contains(
            "| empty run | not reported | - | - | - | - | - | timed out in Idle | - | 0.0 |"
        ));
    }

    #[test]
    fn non_finite_samples_are_skipped_not_drawn() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let mut run = synthetic_run("experiment-2-7cm", 300);
        for (i, record) in run.records.iter_mut().enumerate() {
            if i % 7 == 0 {
                record.part_true_base_m[0] = f64::NAN;
                record.part_est_yaw_rad = Some(f64::INFINITY);
                record.tool_true_base_m = [f64::NAN; 3];
                record.part_sigma_m = f64::NAN;
            }
        }
        run.layout.camera_centre_base_m = [f64::NAN; 3];
        run.duration_s = f64::NAN;
        write_run_outputs(&run, tmp.path()).expect("write outputs");
        check_pngs(&tmp.path().join("experiment-2-7cm"));
    }

    #[test]
    fn a_long_run_is_decimated_and_still_written() {
        let tmp = tempfile::tempdir().expect("tempdir");
        let run = synthetic_run("long", 3 * plots::MAX_POINTS + 17);
        write_run_outputs(&run, tmp.path()).expect("write outputs");
        assert_eq!(
            lines(&tmp.path().join("long").join("timeseries.csv")).len(),
            3 * plots::MAX_POINTS + 18
        );
        check_pngs(&tmp.path().join("long"));
    }

    #[test]
    fn directory_names_cannot_leave_the_output_folder() {
        assert_eq!(directory_name("../etc"), "___etc");
        assert_eq!(directory_name(""), "run");
        assert_eq!(directory_name("experiment-2-7cm"), "experiment-2-7cm");
    }
}
