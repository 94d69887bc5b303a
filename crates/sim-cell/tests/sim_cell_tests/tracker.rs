//! The laser tracker of `vatcal sim-cell` over real TCP, read through the line-protocol
//! driver, has the statistics of the in-process tracker of the same hidden truth: the same
//! systematic error (registration error, SMR-nest offsets) and the same noise, in the tracker's
//! own frame until registered; line-of-sight losses and faults are clear errors.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::Duration;

use nalgebra::Vector3;
use vatcal_drivers_tracker::{LineTracker, TrackerConfig};
use vatcal_hardware_traits::{ErrorKind, Operator, OperatorInstruction, PROBE_NEST_TARGET, PositionTracker};
use vatcal_sim::VirtualCell;
use vatcal_sim_cell::{Device, Ports, SimCell, SimCellOptions};

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn options(seed: u64) -> SimCellOptions {
    SimCellOptions { ports: Ports::ephemeral(), time_scale: 1000.0, ..ok(SimCellOptions::paper(seed)) }
}

fn connect(cell: &SimCell) -> LineTracker {
    let config = TrackerConfig { io_timeout: Duration::from_secs(5), ..TrackerConfig::default() };
    ok(LineTracker::connect_tcp(cell.addrs().tracker, config))
}

/// Mean and standard deviation per axis.
fn stats(errors: &[Vector3<f64>]) -> (Vector3<f64>, Vector3<f64>) {
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<Vector3<f64>>() / n;
    let var = errors.iter().map(|e| (e - mean).component_mul(&(e - mean))).sum::<Vector3<f64>>() / (n - 1.0);
    (mean, var.map(f64::sqrt))
}

const READINGS: usize = 150;

#[test]
fn tcp_tracker_has_the_in_process_statistics() {
    let seed = 5;
    let opts = options(seed);
    let pose = opts.tracker_pose;
    let in_process = VirtualCell::new(opts.nominal.clone(), opts.truth.clone(), opts.sim_config(), seed);
    let cell = ok(SimCell::start(opts));
    let mut tcp = connect(&cell);
    let mut local = in_process.tracker();

    // the SMR of TCP 2 at the start pose, and the probe nest's SMR at calibration position 1
    let mut control = ok(TcpStream::connect(cell.addrs().control));
    ok(control.write_all(b"PLACE 1\n"));
    let mut answer = String::new();
    ok(BufReader::new(ok(control.try_clone())).read_line(&mut answer));
    assert_eq!(answer.trim(), "OK PLACE 1");
    ok(in_process.operator().perform(&OperatorInstruction::PlaceProbe { position: 1 }));
    let nest_truth = ok(opts_position(&cell, 1).ok_or("no position 1"));

    for (target, truth_tcp, truth_local) in [
        (2, cell.cell().true_ball_position_mm(2), in_process.true_ball_position_mm(2)),
        (PROBE_NEST_TARGET, Some(nest_truth), Some(nest_truth)),
    ] {
        let (truth_tcp, truth_local) = (truth_tcp.expect("truth"), truth_local.expect("truth"));
        assert!((truth_tcp - truth_local).norm() < 1e-9, "both cells hold the arm at the same pose");
        let over_tcp: Vec<_> =
            (0..READINGS).map(|_| pose.transform_point(&ok(tcp.measure_mm(target))) - truth_tcp).collect();
        let in_proc: Vec<_> = (0..READINGS).map(|_| ok(local.measure_mm(target)) - truth_local).collect();
        let ((m1, s1), (m2, s2)) = (stats(&over_tcp), stats(&in_proc));
        println!(
            "target {target}: mean error over TCP {:.4?} mm, in process {:.4?} mm; σ {:.4?} / {:.4?} mm",
            m1.as_slice(),
            m2.as_slice(),
            s1.as_slice(),
            s2.as_slice()
        );
        // paper noise: 20 µm (3σ) per axis → σ 6.7 µm; standard error of a mean of 150: 0.54 µm
        let sigma = 0.020 / 3.0;
        for axis in 0..3 {
            assert!(
                (m1[axis] - m2[axis]).abs() < 5.0 * sigma * (2.0 / READINGS as f64).sqrt(),
                "target {target} axis {axis}: mean error {:.4} mm over TCP vs {:.4} mm in process",
                m1[axis],
                m2[axis]
            );
            for s in [s1[axis], s2[axis]] {
                assert!(
                    (s / sigma - 1.0).abs() < 0.25,
                    "target {target} axis {axis}: σ {s:.5} mm vs {sigma:.5} mm"
                );
            }
        }
        // the systematic part is there (registration error, nest offset) and the same
        assert!(m2.norm() > 1e-4, "target {target}: a systematic error is simulated ({m2})");
    }
}

fn opts_position(cell: &SimCell, position: u32) -> Option<Vector3<f64>> {
    cell.cell().truth().position(position)
}

#[test]
fn readings_are_in_the_tracker_frame_and_faults_are_clear() {
    let mut opts = options(2);
    opts.tracker_line_of_sight_loss = 0.3;
    let pose = opts.tracker_pose;
    let cell = ok(SimCell::start(opts));
    let mut t = connect(&cell);
    assert!(t.identity().contains("sim-cell tracker"), "{}", t.identity());
    let truth = cell.cell().true_ball_position_mm(1).expect("ball 1");
    let (mut seen, mut lost) = (0, 0);
    for _ in 0..60 {
        match t.measure_mm(1) {
            Ok(p) => {
                seen += 1;
                assert!((p - truth).norm() > 100.0, "raw readings are not in the tank frame");
                assert!((pose.transform_point(&p) - truth).norm() < 0.1, "registered: within noise");
            }
            Err(e) => {
                lost += 1;
                assert_eq!(e.kind(), ErrorKind::OutOfRange, "{e}");
                assert!(e.to_string().contains("line of sight lost"), "{e}");
            }
        }
    }
    assert!((8..=30).contains(&lost) && seen + lost == 60, "about 30 % lost: {lost} of 60");
    let e = t.measure_mm(PROBE_NEST_TARGET).expect_err("no plate placed");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.to_string().contains("probe plate is not placed"), "{e}");
    let e = t.measure_mm(9).expect_err("no TCP 9");
    assert!(e.to_string().contains("unknown target"), "{e}");

    cell.tracker().set_garbled(true);
    assert_eq!(t.measure_mm(1).expect_err("garbled").kind(), ErrorKind::Protocol);
    cell.tracker().set_garbled(false);
    let mut quick = ok(LineTracker::connect_tcp(
        cell.addrs().tracker,
        TrackerConfig { io_timeout: Duration::from_millis(100), ..TrackerConfig::default() },
    ));
    cell.set_stalled(Device::Tracker, true);
    assert!(quick.measure_mm(1).expect_err("stalled").is_timeout());
    cell.set_stalled(Device::Tracker, false);
    cell.drop_connections(Device::Tracker);
    std::thread::sleep(Duration::from_millis(30));
    assert_eq!(t.measure_mm(1).expect_err("dropped").kind(), ErrorKind::Disconnected);
}
