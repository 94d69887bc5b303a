//! `vatcal sim-cell` as a child process: it prints its ports, serves them, and stops cleanly
//! on SIGTERM; bad options and busy ports are clear errors.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const ALL_EPHEMERAL: [&str; 16] = [
    "--meca500-control-port",
    "0",
    "--meca500-monitoring-port",
    "0",
    "--zaber-port",
    "0",
    "--gauge1-port",
    "0",
    "--gauge2-port",
    "0",
    "--gauge3-port",
    "0",
    "--control-port",
    "0",
    "--tracker-port",
    "0",
];

fn vatcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vatcal"))
}

/// Kills the child if the test fails before it stops by itself.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `vatcal sim-cell` with `args` on ephemeral ports; its guard and its stdout.
fn spawn_sim_cell(args: &[&str]) -> (Guard, BufReader<std::process::ChildStdout>) {
    let child = vatcal()
        .arg("sim-cell")
        .args(args)
        .args(ALL_EPHEMERAL)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn vatcal sim-cell");
    let mut guard = Guard(child);
    let stdout = BufReader::new(guard.0.stdout.take().expect("stdout"));
    (guard, stdout)
}

fn wait_exit(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("try_wait") {
            return status;
        }
        assert!(start.elapsed() < limit, "vatcal sim-cell did not stop within {limit:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn prints_its_ports_serves_them_and_stops_on_sigterm() {
    let (mut guard, mut stdout) =
        spawn_sim_cell(&["--bind", "127.0.0.1", "--seed", "3", "--time-scale", "100", "--no-noise"]);
    let mut ports = std::collections::HashMap::new();
    for _ in 0..8 {
        let mut line = String::new();
        stdout.read_line(&mut line).expect("read a line");
        let words: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(words.len(), 3, "{line:?}");
        assert_eq!(words[0], "listening", "{line:?}");
        let addr: SocketAddr = words[2].parse().expect("an address");
        assert!(addr.ip().is_loopback() && addr.port() != 0, "{line:?}");
        ports.insert(words[1].to_owned(), addr);
    }
    let names = [
        "meca500-control",
        "meca500-monitoring",
        "zaber",
        "gauge-1",
        "gauge-2",
        "gauge-3",
        "cell-control",
        "tracker",
    ];
    for name in names {
        assert!(ports.contains_key(name), "no {name} in {ports:?}");
    }
    let mut banner = String::new();
    stdout.read_line(&mut banner).expect("banner line");
    assert!(banner.contains("seed 3") && banner.contains("noise off"), "{banner}");

    // the Meca500 greets, the operator answers, a gauge reads (nothing touches: on its stop)
    let mut meca = TcpStream::connect(ports["meca500-control"]).expect("connect meca500");
    meca.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
    let mut buf = [0u8; 64];
    let n = meca.read(&mut buf).expect("banner");
    assert!(String::from_utf8_lossy(&buf[..n]).starts_with("[3000][Connected to Meca500"));
    let control = TcpStream::connect(ports["cell-control"]).expect("connect control");
    control.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
    let mut reader = BufReader::new(control.try_clone().expect("clone"));
    (&control).write_all(b"PLACEMENT?\n").expect("write");
    let mut answer = String::new();
    reader.read_line(&mut answer).expect("answer");
    assert_eq!(answer, "PLACEMENT NONE\n");
    let gauge = TcpStream::connect(ports["gauge-2"]).expect("connect gauge");
    gauge.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
    (&gauge).write_all(b"?\r").expect("write");
    let mut value = Vec::new();
    BufReader::new(gauge.try_clone().expect("clone")).read_until(b'\r', &mut value).expect("value");
    assert_eq!(String::from_utf8_lossy(&value), "-006.0000\r");

    let pid = guard.0.id().to_string();
    let status = Command::new("kill").args(["-TERM", &pid]).status().expect("kill -TERM");
    assert!(status.success());
    let status = wait_exit(&mut guard.0, Duration::from_secs(10));
    assert!(status.success(), "exit status {status:?}");
    let mut rest = String::new();
    stdout.read_to_string(&mut rest).expect("rest of stdout");
    assert!(rest.contains("stopped"), "{rest}");
    let mut meca_after = [0u8; 1];
    assert!(matches!(meca.read(&mut meca_after), Ok(0) | Err(_)), "sockets closed");
}

/// `--model` with a six-joint arm without a guide (the UR5e): every port but the Zaber one.
#[test]
fn a_six_joint_arm_cell_has_no_zaber_port() {
    let model = format!("{}/../../fixtures/ur5e.toml", env!("CARGO_MANIFEST_DIR"));
    let (mut guard, mut stdout) =
        spawn_sim_cell(&["--bind", "127.0.0.1", "--model", &model, "--time-scale", "100"]);
    let mut names = Vec::new();
    loop {
        let mut line = String::new();
        assert!(stdout.read_line(&mut line).expect("read a line") > 0, "stdout closed: {names:?}");
        if line.starts_with("vatcal sim-cell:") {
            break;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        assert_eq!((words.len(), words[0]), (3, "listening"), "{line:?}");
        names.push(words[1].to_owned());
    }
    assert_eq!(
        names,
        ["meca500-control", "meca500-monitoring", "gauge-1", "gauge-2", "gauge-3", "cell-control", "tracker"]
    );
    let pid = guard.0.id().to_string();
    assert!(Command::new("kill").args(["-TERM", &pid]).status().expect("kill -TERM").success());
    assert!(wait_exit(&mut guard.0, Duration::from_secs(10)).success());
}

#[test]
fn bad_options_and_busy_ports_are_clear_errors() {
    let out = vatcal().args(["sim-cell", "--time-scale", "0"]).args(ALL_EPHEMERAL).output().expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("time_scale") && err.contains("positive"), "{err}");

    let busy = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = busy.local_addr().expect("addr").port().to_string();
    let mut args: Vec<&str> = ALL_EPHEMERAL.to_vec();
    args[5] = &port; // --zaber-port
    let out = vatcal().arg("sim-cell").args(&args).output().expect("run");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("zaber") && err.contains(&port), "{err}");

    let out = vatcal().args(["sim-cell", "--truth", "/nonexistent/truth.toml"]).args(ALL_EPHEMERAL).output();
    let out = out.expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("truth"));
}
