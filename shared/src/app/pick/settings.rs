//! The pick's tuning: heights, speeds, dwell times, timeouts and fault limits.
//!
//! These are properties of the gripper and of how cautious the cell should be,
//! not of where the camera, the disc or the robot stand (those are calibrated).

/// Every tunable of the pick, with the defaults the simulator's experiments use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PickSettings {
    /// The grasp-point height of the sweeps that show the marks to the camera
    /// before anything is known: the cell's travel height, which the user
    /// keeps clear of any disc and part (see `search`).
    pub search_tool_height_m: f32,
    /// The search sweeps joint 1 over its whole range less this margin at
    /// each end, rad.
    pub search_joint1_margin_rad: f32,
    /// The search's sweeps are this far apart in radius, m: less than the
    /// width of the camera's view at travel height (a camera that frames the
    /// 0.9 m disc sees at least 0.6 m across there).
    pub search_radius_step_m: f32,
    /// The search's radii keep within this fraction of the arm's stretch.
    pub search_max_stretch: f32,
    /// When every sweep has passed and the marks were seen, but fewer times
    /// than `min_effector_sightings`, the arm goes back over where they were
    /// seen most and passes to and fro over them this many times, slowly:
    /// through images a pair is labelled once it has been seen in two frames
    /// 5 cm apart, which a narrow view at the band's edge gives only to a
    /// slow pass (holding still gave one place, and the view's edge).
    pub search_look_passes: u8,
    /// The look's passes reach this far either side of the sightings, m of
    /// arc (wider than the marks' spread about the flange).
    pub search_look_half_width_m: f32,
    /// The look's passes go no faster than this, m/s.
    pub search_look_speed_m_s: f32,
    /// The search's sweeps go no faster than this, m/s: through images the
    /// front end labels the marks only after several frames in view.
    pub search_speed_m_s: f32,
    /// Seen often enough, the marks count as out of the camera's view after
    /// this long unseen: the search halts and goes back over where they were
    /// seen, s. The first estimate needs the sightings of a whole crossing
    /// of the view: from the few at its edge where the count is first
    /// reached, the disc's height came out 20 cm off.
    pub search_out_of_view_s: f32,
    /// Frames showing the part before the search halts: the first
    /// estimate needs it. At a sweep's end the arm holds, clear of the
    /// disc, until the camera has shown it this often, or for `part_wait_s`
    /// at most (then the estimate says what it lacks).
    pub min_part_frames: u32,
    /// See `min_part_frames`, s.
    pub part_wait_s: f32,
    /// Sightings of the marks needed before the first estimate.
    pub min_effector_sightings: u32,
    /// Grasp-point heights above the part's top at which the marks are shown for
    /// the robot-to-disc calibration, highest first (the arm descends in steps
    /// the camera confirms: `max_descent_step_m`), and how long each pose is held.
    pub calibration_heights_m: [f32; 3],
    /// How long each calibration pose is held (see `calibration_heights_m`).
    pub calibration_dwell_s: f32,
    /// From this many calibration poses on, an estimate is asked for after
    /// each pose while the arm goes on to the next; one that meets the
    /// `calibrated_sigma_*` ends the calibration there (see `early`). Three
    /// poses, one per height of `calibration_heights_m`, have shown the marks
    /// down to the lowest.
    pub early_estimate_after_poses: u8,
    /// The part in the base frame known this well (1-sigma, the root of the
    /// horizontal covariance's trace at the worst disc angle) ends the
    /// calibration before the last pose, m.
    pub calibrated_sigma_horizontal_m: f32,
    /// The same for the part's height in the base frame, m.
    pub calibrated_sigma_vertical_m: f32,
    /// The same for its yaw, rad.
    pub calibrated_sigma_yaw_rad: f32,
    /// Hover height above the grasp point while intercepting and tracking.
    pub hover_height_m: f32,
    /// How long tracking must hold the gripper within `track_tolerance_m`
    /// before descending (the most time it may take: `track_window_s`).
    pub track_settle_s: f32,
    /// How close tracking must hold the gripper (see `track_settle_s`).
    pub track_tolerance_m: f32,
    /// The descent from hover height to the grasp point, s.
    pub descend_s: f32,
    /// How long the gripper settles at the grasp point before closing, s:
    /// at least this, then until the grasp point has stayed within
    /// `close_tolerance_m` of its reference for `close_hold_s`, at most
    /// `grasp_settle_max_s` where the plan proved the grasp window for it
    /// (`grasp_settle_s` otherwise).
    pub grasp_settle_s: f32,
    /// The longest settle before the gripper closes regardless, s.
    pub grasp_settle_max_s: f32,
    /// How close the grasp point must stay to its reference before the
    /// gripper closes, m: a joint that stuck where the descent turned it
    /// round (Coulomb friction off the nominal model's) winds Eq 23's
    /// feedback up and then slips, at up to 35 mm/s against the part;
    /// closing on the slip misses. Four times the settle's usual error.
    pub close_tolerance_m: f32,
    /// How long the grasp point must stay within `close_tolerance_m`, s
    /// (held that long, its mean speed off the part's is at most
    /// `2 close_tolerance_m / close_hold_s`).
    pub close_hold_s: f32,
    /// How long the gripper takes to close, s.
    pub grasp_close_s: f32,
    /// How far the part is lifted off the disc, m.
    pub lift_height_m: f32,
    /// How long the lift takes, s.
    pub lift_s: f32,
    /// Height above the drop-off from which the part is lowered, and the release dwell.
    pub drop_hover_m: f32,
    /// How long the gripper stays open over the drop-off (see `drop_hover_m`).
    pub release_s: f32,
    /// The longest track the intercept's plan allows for: its grasp window
    /// (`window`) is checked for a track from `track_settle_s` to this long.
    /// A track not settled by then is abandoned (the part would leave the
    /// window the plan checked) and planned again, or stops with
    /// `TrackingError` after `max_intercept_attempts`.
    pub track_window_s: f32,
    /// The conveyor counts as steady (stopped or turning evenly) below this |alpha|.
    pub steady_alpha_rad_s2: f32,
    /// ... or below this fraction of its speed |omega| (1/s), whichever is
    /// larger: a drive's speed ripple grows with its speed.
    pub steady_alpha_per_omega: f32,
    /// Most time spent waiting for a steady conveyor and a feasible intercept.
    pub locate_timeout_s: f32,
    /// Simulated time allowed for a background estimate or plan before its
    /// result is used (results are applied at this fixed delay, so a run is
    /// deterministic whatever the processor's speed).
    pub estimate_budget_s: f32,
    /// The same for an intercept plan (see `estimate_budget_s`): the plan
    /// starts this long after its request, so it is planned from where the
    /// part will be then. A plan that comes later than that is dropped and
    /// planned again with a longer lead (see `max_plan_lead_s`).
    pub plan_budget_s: f32,
    /// Longest wait for an estimate before the pick stops with `Timeout`. A
    /// late estimate is still good (the arm holds still meanwhile and the
    /// estimate is stamped with its request's time), so this only catches a
    /// worker that hangs; it is above what the final estimate takes on a
    /// 168 MHz Cortex-M4F (about 14 s, docs/performance.md).
    pub estimate_timeout_s: f32,
    /// The longest lead an intercept plan is given after its results came
    /// late (see `plan_budget_s`).
    pub max_plan_lead_s: f32,
    /// A calibration is refused when its 1-sigma part or base position exceeds these.
    pub max_part_sigma_m: f32,
    /// The base position's limit (see `max_part_sigma_m`).
    pub max_base_sigma_m: f32,
    /// The marks are shown once more (at most `max_calibration_rounds`
    /// rounds in all) until the part in the base frame is this many sigmas
    /// inside the gripper's horizontal capture (`CellConfig::grasp_capture_m`;
    /// the sigma is the root of the horizontal covariance's trace, so a miss
    /// beyond k of them has probability `exp(-k^2)`: 2.5 is 0.2 %).
    pub sure_horizontal_sigmas: f32,
    /// The same for the height and the yaw, one axis each (3.0 is 0.3 %).
    pub sure_axis_sigmas: f32,
    /// The most calibration rounds (see `sure_horizontal_sigmas`).
    pub max_calibration_rounds: u8,
    /// Faults: no paired camera frame for this long while vision is needed; the
    /// gripper this far from its reference.
    pub vision_stale_s: f32,
    /// The tracking fault's limit (see `vision_stale_s`).
    pub tracking_error_limit_m: f32,
    /// Longest gap between two control periods before the pick stops
    /// (ControlStall): a motion planned before the gap is not carried on.
    pub stall_limit_s: f32,
    /// Holding after a stop: Eq 23's integral runs this long into the hold,
    /// then is frozen (a live integral hunts in the joints' friction).
    pub hold_settle_s: f32,
    /// A final calibration whose reprojection RMS exceeds this does not fit one
    /// camera pose (the camera moved while the marks were shown): refused.
    pub max_rms_reprojection_px: f32,
    /// ...and one whose robust fit rejected more than this fraction of the
    /// detections (about the points of its frames) fits no single cell.
    pub max_rejected_fraction: f32,
    /// View monitor (after the final calibration): a frame is inconsistent when
    /// the disc's centre, or its reference mark across the mark's circle, lies
    /// further than this from where the calibrated camera puts it...
    pub view_residual_px: f32,
    /// ...and this many inconsistent frames in a row mean the camera moved.
    pub view_strikes: u8,
    /// Largest movement of the part along its circle that missed conveyor
    /// counts may cause before the pick stops (ConveyorSlip).
    pub slip_tolerance_m: f32,
    /// Speed supervision on the encoders' speeds (the plans stay within 70 %
    /// of the limits, corrections take them to 90 %): beyond the first
    /// fraction of a limit the pick stops along its path (JointOverspeed);
    /// beyond the second the joint brake takes over.
    pub overspeed_stop_factor: f32,
    /// The joint brake's fraction of a speed limit (see `overspeed_stop_factor`).
    pub overspeed_brake_factor: f32,
    /// While following the part, the flange's reference must stay within this
    /// fraction of the arm's stretch (plans keep to 0.93) and this far from
    /// the base axis (the shoulder singularity; plans keep 0.30 m).
    pub max_follow_stretch: f32,
    /// The least distance from the base axis while following (see `max_follow_stretch`).
    pub min_follow_radius_m: f32,
    /// A controlled stop decelerates to rest over this time (rising `stop_rise_m`
    /// when near the part), then holds.
    pub stop_s: f32,
    /// How far a stop near the part rises (see `stop_s`).
    pub stop_rise_m: f32,
    /// A stop starts from at most these speeds and acceleration (the pick
    /// never commands more), whatever the reference said.
    pub stop_max_speed_m_s: f32,
    /// A stop's largest starting yaw rate (see `stop_max_speed_m_s`).
    pub stop_max_yaw_rate_rad_s: f32,
    /// A stop's largest starting acceleration (see `stop_max_speed_m_s`).
    pub stop_max_acceleration_m_s2: f32,
    /// A reference may move at most these speeds' worth per period plus these
    /// margins; beyond, it leapt (ReferenceJump).
    pub reference_step_m: f32,
    /// The yaw margin a period (see `reference_step_m`).
    pub reference_step_rad: f32,
    /// Extra time a motion phase may take beyond its planned duration.
    pub motion_timeout_margin_s: f32,
    /// The largest fraction of a joint's speed limit a reference may ask for
    /// (`J^+` of its twist at the measured configuration, every period): the
    /// plans keep to 0.7, the intercept's live correction adds a little.
    /// Beyond it the pick stops (JointOverspeed) with the stop's start speed
    /// scaled back within the limits.
    pub reference_speed_factor: f32,
    /// The intercept's live correction absorbs the part's departure from the
    /// plan's prediction (the disc's speed ripple) up to this distance of the
    /// grasp point, and a conveyor speed within the larger of these of the
    /// plan's; beyond them the conveyor changed under the plan (it stopped,
    /// sped up, reversed) and the plan's checks of reach and joint speed no
    /// longer hold: the intercept is abandoned, the arm brought to rest and
    /// back to where the part was located from, and a new one planned once
    /// the conveyor is steady.
    pub max_intercept_correction_m: f32,
    /// The conveyor speed change the correction absorbs, rad/s (see
    /// `max_intercept_correction_m`).
    pub max_conveyor_speed_change_rad_s: f32,
    /// The same as a fraction of the plan's speed (see `max_intercept_correction_m`).
    pub max_conveyor_speed_change_fraction: f32,
    /// Intercepts planned for one part before the pick gives up (PartUnreachable).
    pub max_intercept_attempts: u8,
    /// A refreshed estimate replaces the one in use over this long, s: the
    /// part's state blends from one to the other (see `refresh`).
    pub estimate_fade_s: f32,
    /// A refreshed estimate that moves the grasp point further than this is
    /// not adopted, m (twice the gripper's horizontal capture).
    pub refresh_max_shift_m: f32,
    /// Before the calibration is accepted the flange goes at most this far
    /// below the lowest height at which the camera has seen the gripper's
    /// marks (BelowSafeHeight otherwise): it descends to the calibration
    /// poses in steps the camera confirms, not on the estimate's word alone.
    pub max_descent_step_m: f32,
}

impl Default for PickSettings {
    fn default() -> Self {
        Self {
            search_tool_height_m: 0.70,
            search_joint1_margin_rad: 0.1,
            search_radius_step_m: 0.2,
            search_max_stretch: 0.9,
            search_look_passes: 4,
            search_look_half_width_m: 0.2,
            search_look_speed_m_s: 0.06,
            search_speed_m_s: 0.35,
            search_out_of_view_s: 1.0,
            min_part_frames: 10,
            part_wait_s: 30.0,
            min_effector_sightings: 6,
            calibration_heights_m: [0.35, 0.20, 0.08],
            calibration_dwell_s: 0.6,
            early_estimate_after_poses: 3,
            calibrated_sigma_horizontal_m: 0.0008,
            calibrated_sigma_vertical_m: 0.0012,
            calibrated_sigma_yaw_rad: 0.0017,
            hover_height_m: 0.06,
            track_settle_s: 0.3,
            track_tolerance_m: 0.003,
            descend_s: 0.7,
            grasp_settle_s: 0.15,
            grasp_settle_max_s: 0.4,
            close_tolerance_m: 0.25e-3,
            close_hold_s: 0.05,
            grasp_close_s: 0.3,
            lift_height_m: 0.15,
            lift_s: 1.2,
            drop_hover_m: 0.10,
            release_s: 0.4,
            track_window_s: 0.6,
            steady_alpha_rad_s2: 0.2,
            steady_alpha_per_omega: 0.3,
            locate_timeout_s: 40.0,
            estimate_budget_s: 1.0,
            plan_budget_s: 0.25,
            estimate_timeout_s: 30.0,
            max_plan_lead_s: 2.0,
            max_part_sigma_m: 0.005,
            max_base_sigma_m: 0.03,
            sure_horizontal_sigmas: 2.5,
            sure_axis_sigmas: 3.0,
            max_calibration_rounds: 4,
            vision_stale_s: 2.0,
            tracking_error_limit_m: 0.03,
            stall_limit_s: 0.02,
            hold_settle_s: 0.3,
            max_rms_reprojection_px: 2.0,
            max_rejected_fraction: 0.08,
            view_residual_px: 6.0,
            view_strikes: 4,
            slip_tolerance_m: 0.003,
            overspeed_stop_factor: 0.97,
            overspeed_brake_factor: 1.1,
            max_follow_stretch: 0.97,
            min_follow_radius_m: 0.22,
            stop_s: 0.6,
            stop_rise_m: 0.05,
            stop_max_speed_m_s: 1.0,
            stop_max_yaw_rate_rad_s: 1.5,
            stop_max_acceleration_m_s2: 5.0,
            reference_step_m: 0.005,
            reference_step_rad: 0.02,
            motion_timeout_margin_s: 2.0,
            reference_speed_factor: 0.95,
            max_intercept_correction_m: 0.08,
            max_conveyor_speed_change_rad_s: 0.1,
            max_conveyor_speed_change_fraction: 0.2,
            max_intercept_attempts: 3,
            max_descent_step_m: 0.20,
            estimate_fade_s: 0.5,
            refresh_max_shift_m: 0.01,
        }
    }
}

/// `value <= limit`, false when either is NaN: limits are checked so that a
/// NaN fails them.
pub fn at_most(value: f32, limit: f32) -> bool {
    value <= limit
}
