//! The messages of protocol v6 (v1's, with `TriggerEvent` and
//! `CostUnit::Nanoseconds` appended in v2; `CellConfig` without the pixel
//! noise in v3; the homing inputs in `SensorSample` and `CellConfig` in v5;
//! the calibrator's per-observation cost in `JobCosts` in v6). They are postcard-encoded, so the order of
//! fields and of enum variants is part of the wire format: append, never reorder.

use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

pub use super::pick::{CalibrationReport, CellConfig, FaultCause, PickPhase, PickTelemetry};

/// Longest peer / board name carried in the handshake, in bytes.
pub const MAX_NAME_LEN: usize = 24;
/// Longest firmware version string, in bytes.
pub const MAX_VERSION_LEN: usize = 16;
/// Most labelled image points in one camera feature frame: disc centre,
/// reference point, up to 8 part features, 2 end-effector points, and room to spare.
pub const MAX_FEATURE_POINTS: usize = 24;
/// Joints of the PUMA 560.
pub const JOINTS: usize = 6;

/// Which physical mark an image point is the image of (the frame contract's
/// `center_px`, `reference_px`, `part_px[i]`, `effector_px[i]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PointLabel {
    /// The disc's centre mark (`center_px`).
    DiscCenter,
    /// The reference mark at the paper's radius L (`reference_px`).
    Reference,
    /// Part feature `i`, in the part's fixed feature order.
    Part(u8),
    /// End-effector point `i` (0 or 1).
    Effector(u8),
}

/// One detected image point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LabeledPoint {
    /// Which mark this is the image of.
    pub label: PointLabel,
    /// Pixel coordinates, u right, v down, `(0, 0)` the top-left pixel centre.
    pub u_px: f32,
    /// Pixel row coordinate, down (see `u_px`).
    pub v_px: f32,
}

/// What the vision computer found in one camera frame. Points that were not
/// detected are simply absent. The controller pairs the frame with the encoder
/// values it latched when it fired `trigger_id`, so vision latency does not bias
/// the conveyor angle of the observation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraFeatureFrame {
    /// The trigger the camera was fired with (pairs the frame with the latched encoders).
    pub trigger_id: u32,
    /// Exposure time on the vision computer's clock, microseconds.
    pub capture_time_us: u64,
    /// The points detected, each labelled.
    pub points: Vec<LabeledPoint, MAX_FEATURE_POINTS>,
    /// The disc's rim as this frame shows it, where the vision computer
    /// measures it (`crate::detection::rim`). Added in v9.
    pub rim: Option<RimEllipse>,
}

/// The disc's rim in one frame: an ellipse in pinhole pixels (as the points).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RimEllipse {
    /// Centre, px.
    pub centre_px: [f32; 2],
    /// Semi-axes along its own axes, px.
    pub semi_axes_px: [f32; 2],
    /// Angle of its first axis from the u axis, rad.
    pub angle_rad: f32,
    /// Standard deviation of its mean radius from this frame, px.
    pub sigma_px: f32,
}

/// Encoder readings of the plant, sent by a simulated (or remote) plant when the
/// controller runs against it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorSample {
    /// Sequence number, echoed by the answering command.
    pub seq: u32,
    /// The sample's time on the plant's clock, microseconds.
    pub time_us: u64,
    /// Joint encoder counts (the sign convention and counts per radian are the board's).
    pub joint_counts: [i32; JOINTS],
    /// Conveyor encoder counter; it wraps around, the receiver unwraps it.
    pub conveyor_counts: u32,
    /// The gripper's part-present switch: its jaws are closed on a part.
    pub part_in_gripper: bool,
    /// Each joint's potentiometer, radians (the board's ADC reading through
    /// its commissioning scale): the coarse angle homing starts from. Added
    /// in v5.
    pub joint_pots_rad: [f32; JOINTS],
    /// Each joint's counter as its last index pulse latched it (the board's
    /// capture register: it holds until the next pulse), `None` before the
    /// first pulse since power-on: homing's exact reference. Held, not
    /// cleared per sample, so a sample the controller never reads (a board
    /// running free) loses no pulse. Added in v5.
    pub joint_index_counts: [Option<i32>; JOINTS],
}

impl SensorSample {
    /// No index pulse latched in any joint since power-on.
    pub const NO_INDEX: [Option<i32>; JOINTS] = [None; JOINTS];
}

/// Gripper jaws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum GripperCommand {
    /// Jaws open (release).
    Open,
    /// Jaws closed (grasp).
    Close,
}

/// Joint torques for the plant's servo drives.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ActuatorCommand {
    /// The sequence number of the sample this command answers.
    pub seq: u32,
    /// Joint torques, N m, joint 1 first.
    pub joint_torque_nm: [f32; JOINTS],
    /// What the gripper's jaws do.
    pub gripper: GripperCommand,
    /// Fire the camera with this trigger id in this period.
    pub camera_trigger: Option<u32>,
}

/// The controller's coarse mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ControllerMode {
    /// No pick configured.
    Idle,
    /// A pick is configured and runs.
    Running,
    /// The pick stopped on a fault.
    Faulted,
}

/// Controller status and link telemetry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ControllerStatus {
    /// The controller's coarse mode.
    pub mode: ControllerMode,
    /// Control-loop periods executed since boot (proves the executor and time driver run).
    pub control_ticks: u64,
    /// Valid frames received since boot.
    pub frames_received: u32,
    /// Frames rejected by the decoder since boot (corrupt, oversized, bad CRC).
    pub frames_rejected: u32,
    /// Valid frames the controller did not expect (e.g. a controller-only message).
    pub frames_unexpected: u32,
    /// Control periods that overran their deadline.
    pub deadline_misses: u32,
}

/// The kind of a data frame being acknowledged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MessageKind {
    /// A [`Message::CameraFeatures`] frame (token: its trigger id).
    CameraFeatures,
    /// A [`Message::SensorSample`] (token: its sequence number).
    SensorSample,
    /// A [`Message::ActuatorCommand`] (token: its sequence number).
    ActuatorCommand,
    /// A cell configuration (token 0).
    Configure,
}

/// What went wrong, in an error report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorCode {
    /// A frame's COBS body was malformed.
    CorruptFrame,
    /// A frame's CRC did not match.
    BadCrc,
    /// A frame was longer than the protocol's maximum.
    OversizedFrame,
    /// A frame passed its CRC but did not hold one valid message.
    BadMessage,
    /// The peer speaks another protocol version.
    UnsupportedVersion,
    /// A data frame came before a successful handshake.
    HandshakeRequired,
    /// A message only the controller sends was sent to it.
    UnexpectedMessage,
    /// A cell configuration was refused; `detail` is the index of the first bad
    /// field in `CellConfig`'s declaration order.
    BadConfiguration,
    /// A cell configuration was refused because the cell was not ready for
    /// one: the pick was moving the arm, a joint was not at rest, the gripper
    /// held a part, or the drives were on (`shared::safety::reconfigure`).
    /// `detail` is `ReconfigureRefusal::detail`: the kind in the upper 16 bits
    /// (1 pick active, 2 joint moving, 3 motion unknown, 4 gripper holds,
    /// 5 drives on), the pick phase's or joint's index in the lower 16. The
    /// running controller is kept; send the configuration again once the
    /// pick has ended and the arm is at rest. It is the last code, so the
    /// others' encodings do not depend on it; a host that does not know it
    /// decodes this report as a bad message and still sees no `Ack` of its
    /// configuration.
    ConfigurationRefusedActive,
}

impl ErrorCode {
    /// The receiver refused a damaged frame (the frame is lost; its sender
    /// learns it from this report or from the reply that never comes).
    pub fn is_frame_refusal(self) -> bool {
        matches!(
            self,
            ErrorCode::CorruptFrame
                | ErrorCode::BadCrc
                | ErrorCode::OversizedFrame
                | ErrorCode::BadMessage
        )
    }
}

/// Every message of protocol v3.
///
/// Camera frames make this enum large (~330 bytes); there is no heap to box them
/// and messages live on the stack only while being handled.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Host -> controller: open a session.
    Hello {
        /// The protocol version the host speaks.
        protocol_version: u16,
        /// The host's name, for logs.
        peer_name: String<MAX_NAME_LEN>,
    },
    /// Controller -> host: session accepted.
    HelloAck {
        /// The protocol version the controller speaks.
        protocol_version: u16,
        /// The board's name (emulated or real).
        board_name: String<MAX_NAME_LEN>,
        /// The firmware's version.
        firmware_version: String<MAX_VERSION_LEN>,
        /// Control periods per second.
        control_rate_hz: u32,
        /// The longest frame the controller accepts, bytes.
        max_frame_len: u16,
    },
    /// Vision computer -> controller: one camera frame's detections.
    CameraFeatures(CameraFeatureFrame),
    /// Plant -> controller: one period's encoder readings.
    SensorSample(SensorSample),
    /// Controller -> plant: one period's torques and gripper command.
    ActuatorCommand(ActuatorCommand),
    /// Host -> controller: send a `Status`.
    StatusRequest,
    /// Controller -> host: the controller's mode and link counters.
    Status(ControllerStatus),
    /// Controller -> host: data frame `token` (its trigger id or sequence number)
    /// was the `counter`-th data frame of this session.
    Ack {
        /// Which kind of data frame.
        kind: MessageKind,
        /// Its trigger id or sequence number.
        token: u32,
        /// Data frames of this session so far, this one included.
        counter: u32,
    },
    /// Something was rejected; `detail` is code-specific (e.g. a running count).
    ErrorReport {
        /// What was rejected.
        code: ErrorCode,
        /// Code-specific detail.
        detail: u32,
    },
    /// Host -> controller: arm the pick with the cell's configuration. From then
    /// on every sensor sample is answered with an actuator command.
    Configure(CellConfig),
    /// Controller -> host: estimates at a bounded rate.
    Telemetry(PickTelemetry),
    /// Controller -> host: after each self-calibration.
    CalibrationReport(CalibrationReport),
    /// Host -> controller: send a `RuntimeReport`.
    RuntimeReportRequest,
    /// Controller -> host: what the control loop and the worker cost, and the
    /// stack used (the firmware measures it; the in-process controller cannot).
    RuntimeReport(RuntimeReport),
    /// Controller -> vision side: the camera was triggered, on a controller
    /// that runs on its own ticker (in lock step the trigger id travels in
    /// the `ActuatorCommand`). The frame exposed at this edge comes back as
    /// `CameraFeatures` with this `trigger_id`. Added in protocol v2.
    TriggerEvent(TriggerEvent),
}

/// The camera trigger's edge, as the controller latched the encoders at it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerEvent {
    /// The id the frame of this exposure must carry.
    pub trigger_id: u32,
    /// The edge's instant, microseconds, on the clock that stamped the
    /// encoder reading latched with it: the controller's own where the
    /// encoders are the board's (the STM32F407: the sensor sample's time);
    /// the plant's where the plant keeps its own clock (the emulated board
    /// running free against a simulated plant: the time stamp of the plant
    /// state it latched), so a simulated camera exposes the very state whose
    /// counts the controller pairs with the frame.
    pub time_us: u64,
}

/// What a [`RuntimeReport`]'s costs are counted in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CostUnit {
    /// Not measured (the in-process controller).
    NotMeasured,
    /// Emulated instructions (QEMU with `-icount shift=0`: 1 ns per instruction).
    Instructions,
    /// CPU cycles (the DWT cycle counter of a real Cortex-M4).
    Cycles,
    /// Nanoseconds of wall-clock time (the emulated board running free,
    /// without `-icount`: QEMU's clock follows the host's, so a cost is how
    /// long the period took, preemptions by the host included). Added in v2.
    Nanoseconds,
}

/// Costs and margins measured by the firmware since the cell was configured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RuntimeReport {
    /// What the costs below are counted in.
    pub unit: CostUnit,
    /// Microseconds since boot on the controller's clock (0: not measured).
    pub uptime_us: u64,
    /// Control periods run.
    pub control_ticks: u64,
    /// One control period (sample in to command out): worst and mean.
    pub control_worst: u32,
    /// The mean control period's cost (see `control_worst`).
    pub control_mean: u32,
    /// Background jobs run (estimates and plans).
    pub jobs_run: u32,
    /// The worst job of each kind, in `unit`: what a real board's jobs take,
    /// which a host uses to model their late results
    /// (`host-sim run --job-timing m4f`).
    pub job_worst: JobCosts,
    /// Deepest stack use seen (stack painting) and the stack's size, bytes.
    pub stack_used_bytes: u32,
    /// The stack's size, bytes (see `stack_used_bytes`).
    pub stack_size_bytes: u32,
    /// Control periods that overran their deadline.
    pub deadline_misses: u32,
    /// Outgoing messages dropped because the link's queue was full (telemetry
    /// first; an actuator command is never dropped silently: it counts here too).
    pub messages_dropped: u32,
    /// Observations or news dropped between the firmware's tasks (queue full).
    pub handoffs_dropped: u32,
    /// Job results that arrived after their due time.
    pub late_results: u32,
    /// The worst control period: its index among `control_ticks` and the
    /// pick's phase at its end (where to look for the cost).
    pub control_worst_tick: u64,
    /// The pick's phase at the end of the worst period (see `control_worst_tick`).
    pub control_worst_phase: PickPhase,
    /// The last accepted reconfiguration's cost (building the new pick in
    /// the control loop; 0 before any). It runs in a control period of its
    /// own, with the arm at rest (`shared::safety::reconfigure`), and is not
    /// counted in `control_worst` or as a deadline miss. It is the last
    /// field: a host whose report lacks it refuses this message as a bad
    /// frame (postcard allows no trailing bytes); no other message holds it.
    pub reconfigure_cost: u32,
}

/// The worst cost of each kind of background job (see [`RuntimeReport`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct JobCosts {
    /// A preliminary estimate (after the search; it also chooses the poses).
    pub estimate_preliminary: u32,
    /// A final estimate (after the calibration poses).
    pub estimate_final: u32,
    /// An intercept plan.
    pub plan: u32,
    /// One observation absorbed by the self-calibrator (not a job: the per-frame
    /// update, validation, Step 2's recursive conic and, once its stores are
    /// full, folding one frame into its normal equations). Protocol version 6.
    pub observation: u32,
}

impl JobCosts {
    /// Nothing measured.
    pub const ZERO: Self = Self {
        estimate_preliminary: 0,
        estimate_final: 0,
        plan: 0,
        observation: 0,
    };

    /// The worst of the three jobs.
    pub fn worst(&self) -> u32 {
        self.estimate_preliminary
            .max(self.estimate_final)
            .max(self.plan)
    }
}

impl RuntimeReport {
    /// A report of a controller that measures nothing.
    pub const fn not_measured(control_ticks: u64) -> Self {
        Self {
            unit: CostUnit::NotMeasured,
            uptime_us: 0,
            control_ticks,
            control_worst: 0,
            control_mean: 0,
            jobs_run: 0,
            job_worst: JobCosts::ZERO,
            stack_used_bytes: 0,
            stack_size_bytes: 0,
            deadline_misses: 0,
            messages_dropped: 0,
            handoffs_dropped: 0,
            late_results: 0,
            control_worst_tick: 0,
            control_worst_phase: PickPhase::Idle,
            reconfigure_cost: 0,
        }
    }
}
