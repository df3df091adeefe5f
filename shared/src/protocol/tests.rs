//! Property tests of protocol v3: round trips, garbage, corruption.
use super::*;
use heapless::{String, Vec};
use proptest::collection::vec as pvec;
use proptest::prelude::*;

fn arb_name<const N: usize>() -> impl Strategy<Value = String<N>> {
    proptest::string::string_regex(&format!("[ -~é]{{0,{}}}", N / 2))
        .expect("valid regex")
        .prop_map(|s| {
            let mut out = String::new();
            for c in s.chars() {
                if out.push(c).is_err() {
                    break;
                }
            }
            out
        })
}

fn arb_label() -> impl Strategy<Value = PointLabel> {
    prop_oneof![
        Just(PointLabel::DiscCenter),
        Just(PointLabel::Reference),
        any::<u8>().prop_map(PointLabel::Part),
        any::<u8>().prop_map(PointLabel::Effector),
    ]
}

fn arb_point() -> impl Strategy<Value = LabeledPoint> {
    (arb_label(), any::<f32>(), any::<f32>()).prop_map(|(label, u_px, v_px)| LabeledPoint {
        label,
        u_px,
        v_px,
    })
}

fn arb_camera() -> impl Strategy<Value = CameraFeatureFrame> {
    (
        any::<u32>(),
        any::<u64>(),
        pvec(arb_point(), 0..=MAX_FEATURE_POINTS),
        proptest::option::of(any::<[f32; 6]>()),
    )
        .prop_map(|(trigger_id, t, pts, rim)| CameraFeatureFrame {
            trigger_id,
            capture_time_us: t,
            points: Vec::from_slice(&pts).expect("bounded by strategy"),
            rim: rim.map(|[u, v, a, b, angle, sigma]| RimEllipse {
                centre_px: [u, v],
                semi_axes_px: [a, b],
                angle_rad: angle,
                sigma_px: sigma,
            }),
        })
}

fn arb_status() -> impl Strategy<Value = ControllerStatus> {
    (
        prop_oneof![
            Just(ControllerMode::Idle),
            Just(ControllerMode::Running),
            Just(ControllerMode::Faulted)
        ],
        any::<u64>(),
        any::<[u32; 4]>(),
    )
        .prop_map(|(mode, control_ticks, c)| ControllerStatus {
            mode,
            control_ticks,
            frames_received: c[0],
            frames_rejected: c[1],
            frames_unexpected: c[2],
            deadline_misses: c[3],
        })
}

fn arb_kind() -> impl Strategy<Value = MessageKind> {
    prop_oneof![
        Just(MessageKind::CameraFeatures),
        Just(MessageKind::SensorSample),
        Just(MessageKind::ActuatorCommand)
    ]
}

fn arb_code() -> impl Strategy<Value = ErrorCode> {
    prop_oneof![
        Just(ErrorCode::CorruptFrame),
        Just(ErrorCode::BadCrc),
        Just(ErrorCode::OversizedFrame),
        Just(ErrorCode::BadMessage),
        Just(ErrorCode::UnsupportedVersion),
        Just(ErrorCode::HandshakeRequired),
        Just(ErrorCode::UnexpectedMessage),
        Just(ErrorCode::BadConfiguration),
        Just(ErrorCode::ConfigurationRefusedActive),
    ]
}

/// Every message variant, with arbitrary field values (NaN and infinities included).
fn arb_message() -> impl Strategy<Value = Message> {
    prop_oneof![
        (any::<u16>(), arb_name::<MAX_NAME_LEN>()).prop_map(|(protocol_version, peer_name)| {
            Message::Hello {
                protocol_version,
                peer_name,
            }
        }),
        (
            any::<u16>(),
            arb_name::<MAX_NAME_LEN>(),
            arb_name::<MAX_VERSION_LEN>(),
            any::<u32>(),
            any::<u16>()
        )
            .prop_map(|(v, b, f, r, m)| Message::HelloAck {
                protocol_version: v,
                board_name: b,
                firmware_version: f,
                control_rate_hz: r,
                max_frame_len: m,
            }),
        arb_camera().prop_map(Message::CameraFeatures),
        (
            any::<u32>(),
            any::<u64>(),
            any::<[i32; JOINTS]>(),
            any::<u32>(),
            any::<[f32; JOINTS]>(),
            any::<[Option<i32>; JOINTS]>()
        )
            .prop_map(|(seq, time_us, j, c, pots, index)| {
                Message::SensorSample(SensorSample {
                    seq,
                    time_us,
                    joint_counts: j,
                    conveyor_counts: c,
                    part_in_gripper: false,
                    joint_pots_rad: pots,
                    joint_index_counts: index,
                })
            }),
        (
            any::<u32>(),
            any::<[f32; JOINTS]>(),
            any::<bool>(),
            proptest::option::of(any::<u32>())
        )
            .prop_map(|(seq, tau, close, trig)| Message::ActuatorCommand(
                ActuatorCommand {
                    seq,
                    joint_torque_nm: tau,
                    gripper: if close {
                        GripperCommand::Close
                    } else {
                        GripperCommand::Open
                    },
                    camera_trigger: trig,
                }
            )),
        Just(Message::StatusRequest),
        arb_status().prop_map(Message::Status),
        (arb_kind(), any::<u32>(), any::<u32>()).prop_map(|(kind, token, counter)| Message::Ack {
            kind,
            token,
            counter
        }),
        (arb_code(), any::<u32>()).prop_map(|(code, detail)| Message::ErrorReport { code, detail }),
        Just(Message::RuntimeReportRequest),
        (any::<u32>(), any::<u64>()).prop_map(|(trigger_id, time_us)| {
            Message::TriggerEvent(TriggerEvent {
                trigger_id,
                time_us,
            })
        }),
        (any::<u64>(), any::<[u32; 10]>(), 0u8..4).prop_map(|(ticks, v, unit)| {
            Message::RuntimeReport(RuntimeReport {
                unit: match unit {
                    0 => CostUnit::NotMeasured,
                    1 => CostUnit::Instructions,
                    2 => CostUnit::Cycles,
                    _ => CostUnit::Nanoseconds,
                },
                uptime_us: ticks / 3,
                control_ticks: ticks,
                control_worst: v[0],
                control_mean: v[1],
                jobs_run: v[2],
                job_worst: JobCosts {
                    estimate_preliminary: v[3],
                    estimate_final: v[3] / 3,
                    plan: v[3] ^ 7,
                    observation: v[3] / 5,
                },
                stack_used_bytes: v[4],
                stack_size_bytes: v[5],
                deadline_misses: v[6],
                messages_dropped: v[7],
                handoffs_dropped: v[8],
                late_results: v[9],
                control_worst_tick: 1234,
                control_worst_phase: PickPhase::Track,
                reconfigure_cost: v[0] ^ v[9],
            })
        }),
    ]
}

/// Bitwise equality, so that NaN payloads compare equal to themselves.
fn same(a: &Message, b: &Message) -> bool {
    wire_bytes(a) == wire_bytes(b)
}

fn wire_bytes(message: &Message) -> std::vec::Vec<u8> {
    let mut buf = [0u8; 4096];
    ::postcard::to_slice(message, &mut buf)
        .expect("fits")
        .to_vec()
}

fn encode(message: &Message) -> std::vec::Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode_frame(message, &mut buf).expect("every message fits a frame");
    buf[..n].to_vec()
}

fn decode_chunked(stream: &[u8], chunk: usize) -> (std::vec::Vec<Message>, usize) {
    let mut decoder = FrameDecoder::new();
    let mut ok = std::vec::Vec::new();
    let mut rejected = 0;
    for piece in stream.chunks(chunk.max(1)) {
        decoder.push_slice(piece, |r| match r {
            Ok(m) => ok.push(m),
            Err(_) => rejected += 1,
        });
    }
    (ok, rejected)
}

/// `decoded` appears in `sent` in order (each decoded frame is one that was sent, at its place).
fn is_in_order_subsequence(decoded: &[Message], sent: &[Message]) -> bool {
    let mut it = sent.iter();
    decoded.iter().all(|d| it.any(|s| same(s, d)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn every_message_round_trips_in_any_chunking(messages in pvec(arb_message(), 1..12), chunk in 1usize..64) {
        let stream: std::vec::Vec<u8> = messages.iter().flat_map(encode).collect();
        let (decoded, rejected) = decode_chunked(&stream, chunk);
        prop_assert_eq!(rejected, 0);
        prop_assert_eq!(decoded.len(), messages.len());
        for (d, m) in decoded.iter().zip(&messages) {
            prop_assert!(same(d, m), "decoded {:?} != sent {:?}", d, m);
        }
    }

    #[test]
    fn random_bytes_never_panic_and_the_link_recovers(garbage in pvec(any::<u8>(), 0..2048), message in arb_message()) {
        let mut stream = garbage.clone();
        stream.extend(encode(&message));
        let (decoded, _) = decode_chunked(&stream, 7);
        // Whatever the garbage produced, the good frame after it is decoded, last and intact.
        let last = decoded.last().expect("the trailing valid frame decodes");
        prop_assert!(same(last, &message));
    }

    #[test]
    fn a_flipped_dropped_or_inserted_byte_never_yields_a_wrong_message(
        messages in pvec(arb_message(), 1..8),
        position in any::<prop::sample::Index>(),
        mutation in 0u8..3,
        value in any::<u8>(),
        bit in 0u8..8,
    ) {
        let mut stream: std::vec::Vec<u8> = messages.iter().flat_map(encode).collect();
        let at = position.index(stream.len());
        match mutation {
            0 => stream[at] ^= 1 << bit,
            1 => { stream.remove(at); }
            _ => stream.insert(at, value),
        }
        let (decoded, _) = decode_chunked(&stream, 13);
        prop_assert!(is_in_order_subsequence(&decoded, &messages), "a wrong or reordered message was accepted");
        // One byte touches at most two frames (the one it is in and, via a delimiter, a neighbour).
        prop_assert!(decoded.len() + 2 >= messages.len(), "lost {} of {}", messages.len() - decoded.len(), messages.len());
    }
}

#[test]
fn the_largest_messages_fit_the_documented_frame() {
    let worst_name: String<MAX_NAME_LEN> = String::try_from("ÿÿÿÿÿÿÿÿÿÿÿÿ").expect("24 bytes");
    let worst_version: String<MAX_VERSION_LEN> = String::try_from("ÿÿÿÿÿÿÿÿ").expect("16 bytes");
    let point = LabeledPoint {
        label: PointLabel::Effector(255),
        u_px: f32::MAX,
        v_px: f32::MIN,
    };
    let camera = CameraFeatureFrame {
        trigger_id: u32::MAX,
        capture_time_us: u64::MAX,
        points: Vec::from_slice(&[point; MAX_FEATURE_POINTS]).expect("full"),
        rim: Some(RimEllipse {
            centre_px: [f32::MAX; 2],
            semi_axes_px: [f32::MIN; 2],
            angle_rad: f32::MAX,
            sigma_px: f32::MAX,
        }),
    };
    let worst = [
        Message::Hello {
            protocol_version: u16::MAX,
            peer_name: worst_name.clone(),
        },
        Message::HelloAck {
            protocol_version: u16::MAX,
            board_name: worst_name,
            firmware_version: worst_version,
            control_rate_hz: u32::MAX,
            max_frame_len: u16::MAX,
        },
        Message::CameraFeatures(camera),
        Message::SensorSample(SensorSample {
            seq: u32::MAX,
            time_us: u64::MAX,
            joint_counts: [i32::MIN; JOINTS],
            conveyor_counts: u32::MAX,
            part_in_gripper: true,
            joint_pots_rad: [f32::MAX; JOINTS],
            joint_index_counts: [Some(i32::MIN); JOINTS],
        }),
        Message::ActuatorCommand(ActuatorCommand {
            seq: u32::MAX,
            joint_torque_nm: [f32::MAX; JOINTS],
            gripper: GripperCommand::Close,
            camera_trigger: Some(u32::MAX),
        }),
        Message::TriggerEvent(TriggerEvent {
            trigger_id: u32::MAX,
            time_us: u64::MAX,
        }),
        Message::Status(ControllerStatus {
            mode: ControllerMode::Faulted,
            control_ticks: u64::MAX,
            frames_received: u32::MAX,
            frames_rejected: u32::MAX,
            frames_unexpected: u32::MAX,
            deadline_misses: u32::MAX,
        }),
    ];
    for m in &worst {
        let frame = encode(m);
        assert!(frame.len() <= MAX_FRAME_LEN);
        let (decoded, rejected) = decode_chunked(&frame, 1);
        assert_eq!(rejected, 0);
        assert!(same(&decoded[0], m));
    }
}

#[test]
fn oversized_input_is_rejected_then_the_next_frame_decodes() {
    let mut stream = vec![0x55u8; 5 * MAX_FRAME_LEN];
    stream.push(0);
    let good = Message::StatusRequest;
    stream.extend(encode(&good));
    let mut decoder = FrameDecoder::new();
    let mut results = std::vec::Vec::new();
    decoder.push_slice(&stream, |r| results.push(r));
    assert!(
        matches!(results[0], Err(DecodeError::Oversized { discarded }) if discarded == 5 * MAX_FRAME_LEN)
    );
    assert_eq!(results.len(), 2);
    assert_eq!(results[1], Ok(good));
    assert_eq!(decoder.pending(), 0);
}

#[test]
fn crc_valid_frame_with_trailing_bytes_is_a_bad_message() {
    // A StatusRequest payload followed by a stray byte, with a correct CRC over both.
    let mut payload = [0u8; 16];
    let n = postcard::to_slice(&Message::StatusRequest, &mut payload)
        .expect("fits")
        .len();
    payload[n] = 0x42;
    let raw_len = n + 1;
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&payload[..raw_len]);
    let mut raw = payload[..raw_len].to_vec();
    raw.extend(crc.to_le_bytes());
    let mut body = [0u8; 64];
    let body_len = super::cobs::encode(&raw, &mut body).expect("fits");
    let mut stream = vec![0u8];
    stream.extend(&body[..body_len]);
    stream.push(0);
    let mut decoder = FrameDecoder::new();
    let mut results = std::vec::Vec::new();
    decoder.push_slice(&stream, |r| results.push(r));
    assert_eq!(results, vec![Err(DecodeError::BadMessage)]);
}

#[test]
fn a_corrupted_crc_is_reported_with_both_values() {
    let mut frame = encode(&Message::StatusRequest);
    let len = frame.len();
    frame[len - 2] ^= 0x01;
    let (decoded, rejected) = decode_chunked(&frame, 3);
    assert!(decoded.is_empty());
    assert_eq!(rejected, 1);
}

#[test]
fn the_documented_frame_limits_hold() {
    // README and protocol docs state these numbers.
    assert_eq!(MAX_MESSAGE_LEN, 320);
    assert_eq!(MAX_FRAME_LEN, 328);
}

/// The v2 additions are appended: every v1 message keeps its encoding (the
/// new variants' indices come after the old ones). v3 changed `CellConfig`
/// only, v4 appended two fault causes, v5 the homing inputs, v6 the
/// observation's cost in `JobCosts`, v7 the grasp's sigmas in
/// `CalibrationReport`, and the version says so.
#[test]
fn v2_appends_the_trigger_event_and_keeps_v1_encodings() {
    assert_eq!(PROTOCOL_VERSION, 10);
    // postcard writes the variant index first: RuntimeReport was the last of
    // v1 (index 13), TriggerEvent is 14.
    let event = wire_bytes(&Message::TriggerEvent(TriggerEvent {
        trigger_id: 5,
        time_us: 300,
    }));
    assert_eq!(event, vec![14, 5, 0xAC, 0x02]);
    assert_eq!(wire_bytes(&Message::RuntimeReportRequest), vec![12]);
    assert_eq!(wire_bytes(&Message::StatusRequest), vec![5]);
    let mut unit = [0u8; 4];
    assert_eq!(
        ::postcard::to_slice(&CostUnit::Nanoseconds, &mut unit).expect("fits"),
        &[3]
    );
}

/// v5's sensor sample: the homing inputs after the v4 fields, each
/// potentiometer an f32, each index count an option (one byte when none).
#[test]
fn a_v5_sensor_sample_carries_the_potentiometers_and_the_latched_indexes() {
    let sample = SensorSample {
        seq: 7,
        time_us: 1_000,
        joint_counts: [1, -2, 3, -4, 5, -6],
        conveyor_counts: 9,
        part_in_gripper: false,
        joint_pots_rad: [0.5, -1.25, 3.0, 0.0, -0.001, 2.5],
        joint_index_counts: [None, Some(-123_456), None, None, Some(i32::MAX), None],
    };
    let bytes = wire_bytes(&Message::SensorSample(sample));
    let back: Message = ::postcard::from_bytes(&bytes).expect("decodes");
    assert_eq!(back, Message::SensorSample(sample));
    let idle = SensorSample {
        joint_index_counts: SensorSample::NO_INDEX,
        ..sample
    };
    // Six f32 and six option tags on top of the v4 sample.
    let v4_len = wire_bytes(&Message::SensorSample(idle)).len() - 6 * 4 - 6;
    assert_eq!(v4_len, 1 + 1 + 2 + 6 + 1 + 1);
}
