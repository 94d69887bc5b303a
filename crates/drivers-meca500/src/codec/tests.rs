//! Tests of the codec: encoding, parsing, replies, status word, banner and deframing.

use super::*;
use proptest::prelude::*;

fn parse(s: &str) -> Command {
    match parse_command(s) {
        Ok(p) => p.command,
        Err(e) => panic!("{s}: {e}"),
    }
}

#[test]
fn encodes_the_lines_mecademicpy_writes() {
    // protocols.md §1.2: mecademicpy writes exactly these
    assert_eq!(
        Command::MoveJoints([10.0, -20.0, 30.0, 0.0, 45.0, 0.0]).to_text(),
        "MoveJoints(10,-20,30,0,45,0)"
    );
    assert_eq!(
        Command::MoveLinRelTrf([0.01, 0.0, 0.0, 0.0, 0.0, 0.0]).to_text(),
        "MoveLinRelTrf(0.01,0,0,0,0,0)"
    );
    assert_eq!(Command::GetStatusRobot.encode(), b"GetStatusRobot\0");
    assert_eq!(Command::SetRtc(1795314763).to_text(), "SetRtc(1795314763)");
    assert_eq!(Command::SetCtrlPortMonitoring(true).to_text(), "SetCtrlPortMonitoring(1)");
    assert_eq!(Command::Empty.encode(), vec![0u8]);
    assert_eq!(format_number(-0.0000000001), "0");
    assert_eq!(format_number(1e-9), "0.000000001");
}

#[test]
fn parses_the_transcript_commands_of_the_reference() {
    // §1.4 connect sequence and §1.9 error transcript
    let cases = [
        ("-GetRobotSerial", Command::GetRobotSerial, true),
        ("-GetFwVersionFull", Command::GetFwVersionFull, true),
        ("-GetRealTimeMonitoring", Command::GetRealTimeMonitoring, true),
        ("-GetMonitoringInterval", Command::GetMonitoringInterval, true),
        ("-SetRtc(1795314763)", Command::SetRtc(1795314763), true),
        ("-SetCtrlPortMonitoring(1)", Command::SetCtrlPortMonitoring(true), true),
        ("MoveJoints(200,0,0,0,0,0)", Command::MoveJoints([200.0, 0.0, 0.0, 0.0, 0.0, 0.0]), false),
        ("SetCheckpoint(8001)", Command::SetCheckpoint(8001), false),
        ("ResetError", Command::ResetError, false),
        ("ResumeMotion", Command::ResumeMotion, false),
        ("", Command::Empty, false),
    ];
    for (line, cmd, silent) in cases {
        let p = parse_command(line).unwrap_or_else(|e| panic!("{line}: {e}"));
        assert_eq!(p.command, cmd, "{line}");
        assert_eq!(p.silent, silent, "{line}");
    }
}

#[test]
fn parsing_is_case_insensitive_and_tolerates_spaces() {
    assert_eq!(parse("movejoints( 1, 2 ,3,4,5, 6 )"), Command::MoveJoints([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
    assert_eq!(parse("  GETSTATUSROBOT "), Command::GetStatusRobot);
    assert_eq!(parse("GetJoints()"), Command::GetJoints);
    assert_eq!(parse("SetRealTimeMonitoring(all)"), Command::SetRealTimeMonitoring(RealTimeCodes::All));
    assert_eq!(
        parse("SetRealTimeMonitoring(2200, 2210)"),
        Command::SetRealTimeMonitoring(RealTimeCodes::Codes(vec![2200, 2210]))
    );
}

#[test]
fn bad_commands_map_to_the_robot_codes() {
    let code = |s: &str| parse_command(s).map(|_| 0).unwrap_or_else(|e| e.code());
    assert_eq!(code("Dance"), 1001);
    assert_eq!(code("-"), 1001);
    assert_eq!(code("MoveJoints(1,2,3"), 1002);
    assert_eq!(code("MoveJoints(1,2,x,4,5,6)"), 1002);
    assert_eq!(code("MoveJoints(1,,3,4,5,6)"), 1002);
    assert_eq!(code("Move Joints(1)"), 1002);
    assert_eq!(code("MoveJoints(1,2,3)"), 1003);
    assert_eq!(code("Home(1)"), 1003);
    assert_eq!(code("SetCheckpoint(1.5)"), 1003);
    assert_eq!(code("SetEob(2)"), 1003);
}

#[test]
fn parses_the_replies_quoted_in_the_reference() {
    let r = |s: &str| Reply::parse(s.as_bytes()).unwrap_or_else(|e| panic!("{s}: {e}"));
    assert_eq!(r("[2083][M500-0000]"), Reply::new(2083, "M500-0000"));
    assert_eq!(r("[2117][]"), Reply::new(2117, ""));
    assert_eq!(r("[2116][0.015]").values(), Ok(vec![0.015]));
    let st = StatusWord::from_reply(&r("[2007][0,0,0,0,0,1,1]")).unwrap_or_else(|e| panic!("{e}"));
    assert!(!st.activated && st.end_of_block && st.end_of_movement);
    let st = StatusWord::from_reply(&r("[2007][1,1,0,1,1,1,1]")).unwrap_or_else(|e| panic!("{e}"));
    assert!(st.activated && st.homed && st.error && st.paused);
    assert!(r("[1007][Joint 1 over limit ...]").is_error());
    assert!(r("[1011][The robot is already in error.]").is_error());
    assert!(!r("[2005][The error was reset.]").is_error());
    assert!(r("[3070][1]").is_error());
    assert!(!r("[3070][0]").is_error());
    assert!(!r("[3030][8001]").is_error());
    // payload runs to the LAST ']'
    assert_eq!(r("[1001][Unknown command [Foo]]").payload, "Unknown command [Foo]");
    assert_eq!(Reply::parse(b"{\"a\":1}"), Err(ReplyError::Json));
    assert!(matches!(Reply::parse(b"2007 1,1"), Err(ReplyError::MissingCode(_))));
    assert!(matches!(Reply::parse(b"[20x7][1]"), Err(ReplyError::BadCode(_))));
    assert!(matches!(Reply::parse(b"[2007]"), Err(ReplyError::MissingPayload(_))));
    assert_eq!(Reply::parse(&[0x5b, 0xff]), Err(ReplyError::NotAscii));
}

#[test]
fn rt_joint_reply_skips_the_time_stamp() {
    let r = Reply::new(2200, "123456,1,2,3,4,5,6");
    assert_eq!(r.last_six(), Ok([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
    assert!(Reply::new(2200, "1,2,3").last_six().is_err());
    assert!(Reply::new(2026, "1,2,3,4,5,nan").values().is_err());
}

#[test]
fn banner_variants() {
    let b = Banner::from_reply(&Reply::new(3000, "Connected to Meca500 R3 v9.3.0"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((b.model.as_str(), b.revision, b.version), ("Meca500", Some(3), (9, 3, 0)));
    assert_eq!(b.to_text(), "Connected to Meca500 R3 v9.3.0");
    let b = Banner::from_reply(&Reply::new(3000, "Connected to meca500 R4-virtual v10.1.2.1234"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(b.virtual_robot && b.revision == Some(4) && b.version == (10, 1, 2));
    let b =
        Banner::from_reply(&Reply::new(3000, "Connected to Meca500_8.3.5")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((b.revision, b.version), (None, (8, 3, 5)));
    assert!(matches!(
        Banner::from_reply(&Reply::new(3001, "Another user is already connected, closing connection.")),
        Err(BannerError::Refused(_))
    ));
    assert!(matches!(
        Banner::from_reply(&Reply::new(3000, "Connected to Robot R3 v9.3.0")),
        Err(BannerError::UnknownModel(_))
    ));
    assert!(matches!(Banner::from_reply(&Reply::new(3000, "hello")), Err(BannerError::Unparsable(_))));
    assert!(matches!(Banner::from_reply(&Reply::new(2007, "1")), Err(BannerError::NotABanner(_))));
}

#[test]
fn deframer_handles_lf_crlf_and_overlong_input() {
    let mut d = Deframer::nul_or_lf();
    d.push(b"GetJoints\nHome\r\nResetError\0Act");
    let mut frames = Vec::new();
    while let Ok(Some(f)) = d.next_frame() {
        frames.push(f);
    }
    assert_eq!(frames, vec![b"GetJoints".to_vec(), b"Home".to_vec(), b"ResetError".to_vec()]);
    assert_eq!(d.pending(), 3);
    let mut d = Deframer::nul_only();
    d.push(&vec![b'x'; MAX_FRAME_LEN + 1]);
    assert_eq!(d.next_frame(), Err(FrameError::TooLong { max: MAX_FRAME_LEN }));
    assert_eq!(d.pending(), 0);
    // the rest of the overlong frame (up to its NUL) is dropped, then frames come intact
    d.push(b"xxx\0[2007][1]\0");
    assert_eq!(d.next_frame(), Ok(Some(b"[2007][1]".to_vec())));
}

fn arb_number() -> impl Strategy<Value = f64> {
    prop_oneof![(-100_000.0f64..100_000.0), (-1.0f64..1.0), (-36_000i32..36_000).prop_map(f64::from)]
}

fn arb_six() -> impl Strategy<Value = Six> {
    proptest::array::uniform6(arb_number())
}

fn arb_command() -> impl Strategy<Value = Command> {
    use Command as C;
    prop_oneof![
        Just(C::Empty),
        Just(C::ActivateRobot),
        Just(C::Home),
        Just(C::ResetError),
        Just(C::ClearMotion),
        Just(C::GetStatusRobot),
        Just(C::GetRtTargetJointPos),
        arb_number().prop_map(C::SetJointVel),
        arb_number().prop_map(C::SetCartLinVel),
        arb_number().prop_map(C::Delay),
        arb_six().prop_map(C::MoveJoints),
        arb_six().prop_map(C::MoveLinRelTrf),
        arb_six().prop_map(C::MoveLinRelWrf),
        arb_six().prop_map(C::SetTrf),
        any::<u32>().prop_map(C::SetCheckpoint),
        any::<u32>().prop_map(C::SyncCmdQueue),
        any::<bool>().prop_map(C::SetEob),
        any::<bool>().prop_map(C::SetCtrlPortMonitoring),
        (0u64..=u64::from(u32::MAX) * 4).prop_map(C::SetRtc),
        proptest::collection::vec(2200u16..2300, 0..5)
            .prop_map(|c| C::SetRealTimeMonitoring(RealTimeCodes::Codes(c))),
    ]
}

/// Equal up to the written precision (9 decimals).
fn close(a: &Command, b: &Command) -> bool {
    let nums = |c: &Command| -> Vec<f64> {
        match c {
            Command::SetJointVel(v) | Command::SetCartLinVel(v) | Command::Delay(v) => vec![*v],
            Command::MoveJoints(s)
            | Command::MoveLinRelTrf(s)
            | Command::MoveLinRelWrf(s)
            | Command::SetTrf(s) => s.to_vec(),
            _ => Vec::new(),
        }
    };
    std::mem::discriminant(a) == std::mem::discriminant(b)
        && nums(a).len() == nums(b).len()
        && nums(a).iter().zip(nums(b)).all(|(x, y)| (x - y).abs() <= 1e-9 + 1e-15 * x.abs())
        && (!nums(a).is_empty() || a == b)
}

proptest! {
    #[test]
    fn command_round_trip(cmd in arb_command()) {
        let bytes = cmd.encode();
        prop_assert_eq!(bytes.last(), Some(&NUL));
        prop_assert!(bytes[..bytes.len() - 1].iter().all(|&b| b != NUL && b.is_ascii()));
        let mut d = Deframer::nul_or_lf();
        d.push(&bytes);
        let frame = d.next_frame().ok().flatten().unwrap_or_default();
        let back = parse_command(&String::from_utf8_lossy(&frame));
        prop_assert!(back.is_ok(), "{:?}", back);
        let back = back.map(|p| p.command).unwrap_or(Command::Empty);
        prop_assert!(close(&cmd, &back), "{:?} -> {} -> {:?}", cmd, cmd, back);
    }

    #[test]
    fn reply_round_trip(code in 0u16..10_000, payload in "[ -~]{0,40}") {
        let r = Reply::new(code, payload);
        let bytes = r.encode();
        let back = Reply::parse(&bytes[..bytes.len() - 1]);
        // surrounding whitespace is trimmed by the parser, not part of the payload
        prop_assert_eq!(back, Ok(r));
    }

    #[test]
    fn parsers_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..80), text in "[ -~]{0,80}") {
        let _ = Reply::parse(&bytes);
        let _ = parse_command(&String::from_utf8_lossy(&bytes));
        let _ = parse_command(&text);
        if let Ok(r) = Reply::parse(text.as_bytes()) {
            let _ = r.values();
            let _ = r.last_six();
            let _ = StatusWord::from_reply(&r);
            let _ = Banner::from_reply(&Reply::new(3000, r.payload.clone()));
        }
    }

    #[test]
    fn status_word_round_trip(flags in proptest::array::uniform7(any::<bool>())) {
        let s = StatusWord::from_flags(flags);
        prop_assert_eq!(StatusWord::from_reply(&s.to_reply()), Ok(s));
    }

    #[test]
    fn deframing_is_independent_of_tcp_segmentation(
        replies in proptest::collection::vec((0u16..10_000, "[ -~]{0,20}"), 1..8),
        cuts in proptest::collection::vec(0usize..400, 0..10),
    ) {
        let replies: Vec<Reply> = replies.into_iter().map(|(c, p)| Reply::new(c, p)).collect();
        let stream: Vec<u8> = replies.iter().flat_map(Reply::encode).collect();
        let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c % (stream.len() + 1)).collect();
        cuts.push(0);
        cuts.push(stream.len());
        cuts.sort_unstable();
        let mut d = Deframer::nul_only();
        let mut got = Vec::new();
        for w in cuts.windows(2) {
            d.push(&stream[w[0]..w[1]]);
            while let Ok(Some(f)) = d.next_frame() {
                got.push(Reply::parse(&f));
            }
        }
        prop_assert_eq!(got, replies.into_iter().map(Ok).collect::<Vec<_>>());
    }
}
