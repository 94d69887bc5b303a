//! Client of the cell-control port of `vatcal sim-cell` and the automatic operator built on it.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::sync::Mutex;
use std::time::Duration;

use vatcal_hardware_traits::{Clock, Error, ErrorKind, Operator, OperatorInstruction, Result};

const DEVICE: &str = "sim control";

/// A connection to the cell-control port of `vatcal sim-cell` (one request line, one answer
/// line).
#[derive(Debug)]
pub struct SimControl {
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    address: String,
    timeouts: (Duration, Duration),
}

impl SimControl {
    /// Connects to `address` (e.g. `127.0.0.1:55570`); every answer must come within
    /// `io_timeout`.
    ///
    /// # Errors
    /// The connection fails ([`ErrorKind::Timeout`], [`ErrorKind::Disconnected`], ...).
    pub fn connect(address: &str, connect_timeout: Duration, io_timeout: Duration) -> Result<Self> {
        let stream = vatcal_hardware_traits::transport::connect_tcp(address, connect_timeout)
            .map_err(|e| Error::from_io(DEVICE, e).context(format!("connecting to {address}")))?;
        stream.set_read_timeout(Some(io_timeout)).map_err(|e| Error::from_io(DEVICE, e))?;
        stream.set_write_timeout(Some(io_timeout)).map_err(|e| Error::from_io(DEVICE, e))?;
        let writer = stream.try_clone().map_err(|e| Error::from_io(DEVICE, e))?;
        Ok(Self {
            reader: BufReader::new(stream),
            writer,
            address: address.to_owned(),
            timeouts: (connect_timeout, io_timeout),
        })
    }

    /// The simulated cell's virtual time (`TIME?` → `TIME <s>`) \[s\].
    ///
    /// # Errors
    /// An answer that is not `TIME <seconds>`.
    pub fn time_s(&mut self) -> Result<f64> {
        let answer = self.request("TIME?")?;
        answer
            .strip_prefix("TIME ")
            .and_then(|t| t.trim().parse::<f64>().ok())
            .filter(|t| t.is_finite() && *t >= 0.0)
            .ok_or_else(|| Error::new(ErrorKind::Protocol, DEVICE, format!("`TIME?` answered `{answer}`")))
    }

    /// The simulated cell's temperature as its thermometer reads it (`TEMP?` → `TEMP <°C>`;
    /// `TEMP NONE` when the cell has no temperature channel) \[°C\].
    ///
    /// # Errors
    /// `TEMP NONE` ([`ErrorKind::Disconnected`]: no thermometer), or an answer that is not
    /// `TEMP <plausible temperature>` ([`ErrorKind::Protocol`] / [`ErrorKind::OutOfRange`]).
    pub fn temperature_c(&mut self) -> Result<f64> {
        let answer = self.request("TEMP?")?;
        match answer.strip_prefix("TEMP ").map(str::trim) {
            Some("NONE") => Err(Error::new(
                ErrorKind::Disconnected,
                DEVICE,
                "the simulated cell has no temperature channel (`TEMP?` answered `TEMP NONE`)",
            )),
            Some(t) => vatcal_hardware_traits::parse_temperature_c(DEVICE, t),
            None => Err(Error::new(ErrorKind::Protocol, DEVICE, format!("`TEMP?` answered `{answer}`"))),
        }
    }

    /// A second connection to the same port (same timeouts), e.g. for a thermometer beside the
    /// operator.
    ///
    /// # Errors
    /// The connection fails.
    pub fn reconnect(&self) -> Result<Self> {
        Self::connect(&self.address, self.timeouts.0, self.timeouts.1)
    }

    /// A [`SimCellClock`] on a second connection to the same port.
    ///
    /// # Errors
    /// The connection or the first `TIME?` fails.
    pub fn clock(&self) -> Result<SimCellClock> {
        let mut control = Self::connect(&self.address, self.timeouts.0, self.timeouts.1)?;
        let last_s = control.time_s()?;
        Ok(SimCellClock { control: Mutex::new((control, last_s)) })
    }

    /// Sends `line` and returns the answer line (without the line ending).
    fn request(&mut self, line: &str) -> Result<String> {
        self.writer.write_all(format!("{line}\n").as_bytes()).map_err(|e| Error::from_io(DEVICE, e))?;
        self.writer.flush().map_err(|e| Error::from_io(DEVICE, e))?;
        let mut answer = String::new();
        let n = self.reader.read_line(&mut answer).map_err(|e| Error::from_io(DEVICE, e))?;
        if n == 0 {
            return Err(Error::new(
                ErrorKind::Disconnected,
                DEVICE,
                format!("connection closed after `{line}`"),
            ));
        }
        Ok(answer.trim_end_matches(['\r', '\n']).to_string())
    }

    /// Sends `command` and requires the answer `OK <command>`.
    fn command(&mut self, command: &str) -> Result<()> {
        let answer = self.request(command)?;
        if answer == format!("OK {command}") {
            Ok(())
        } else {
            Err(Error::new(
                ErrorKind::Protocol,
                DEVICE,
                format!("`{command}` answered `{answer}` (expected `OK {command}`)"),
            ))
        }
    }

    /// Re-places the probe plate at calibration position `position` (`PLACE <n>`).
    ///
    /// # Errors
    /// Any answer other than `OK PLACE <n>`.
    pub fn place(&mut self, position: u32) -> Result<()> {
        self.command(&format!("PLACE {position}"))
    }

    /// Seats the master ball in the probe, the plate being at `position` (`MASTER <n>`).
    ///
    /// # Errors
    /// Any answer other than `OK MASTER <n>` (e.g. the plate is elsewhere).
    pub fn seat_master(&mut self, position: u32) -> Result<()> {
        self.command(&format!("MASTER {position}"))
    }

    /// Removes the master ball (`MASTER OFF`).
    ///
    /// # Errors
    /// Any answer other than `OK MASTER OFF`.
    pub fn remove_master(&mut self) -> Result<()> {
        self.command("MASTER OFF")
    }

    /// The current placement (`PLACEMENT?` → `PLACEMENT <n>`, or `PLACEMENT NONE` before the
    /// first `PLACE`).
    ///
    /// # Errors
    /// An answer that is neither.
    pub fn placement(&mut self) -> Result<Option<u32>> {
        let answer = self.request("PLACEMENT?")?;
        let bad = || Error::new(ErrorKind::Protocol, DEVICE, format!("`PLACEMENT?` answered `{answer}`"));
        match answer.strip_prefix("PLACEMENT ").map(str::trim) {
            Some("NONE") => Ok(None),
            Some(n) => n.parse().map(Some).map_err(|_| bad()),
            None => Err(bad()),
        }
    }
}

/// The clock of a simulated cell: its virtual time, read over the cell-control port
/// (`TIME?`), which counts the simulated motions, readings and re-placements exactly as the
/// in-process virtual cell does, whatever the simulator's time scale. A campaign against
/// `vatcal sim-cell --operator auto` stamps its `time_s` with it, so the column means the same
/// as in `vatcal demo`.
///
/// [`Clock::now`] cannot fail: if the port stops answering, it returns the last time read
/// (the campaign's next device call reports the fault). [`Clock::sleep`] sleeps the wall
/// clock: the simulated cell's time advances with its devices' events, not by waiting.
#[derive(Debug)]
pub struct SimCellClock {
    control: Mutex<(SimControl, f64)>,
}

impl Clock for SimCellClock {
    fn now(&self) -> Duration {
        let mut guard = match self.control.lock() {
            Ok(g) => g,
            Err(poisoned) => poisoned.into_inner(),
        };
        let (control, last_s) = &mut *guard;
        if let Ok(t) = control.time_s() {
            *last_s = last_s.max(t);
        }
        Duration::try_from_secs_f64(*last_s).unwrap_or(Duration::ZERO)
    }

    fn sleep(&self, duration: Duration) {
        std::thread::sleep(duration);
    }
}

/// The operator of a simulated cell: re-places the probe plate (`PLACE <n>`) and seats and
/// removes the master ball for probe zeroing (`MASTER <n>`, `MASTER OFF`) through
/// [`SimControl`]; confirms motions at once (nothing to do in the simulator).
#[derive(Debug)]
pub struct SimControlOperator {
    control: SimControl,
    log: Vec<String>,
}

impl SimControlOperator {
    /// An operator on `control`.
    pub fn new(control: SimControl) -> Self {
        Self { control, log: Vec::new() }
    }

    /// Every instruction performed so far, in order.
    pub fn log(&self) -> &[String] {
        &self.log
    }
}

impl Operator for SimControlOperator {
    fn perform(&mut self, instruction: &OperatorInstruction) -> Result<()> {
        match instruction {
            OperatorInstruction::PlaceProbe { position } => self.control.place(*position)?,
            OperatorInstruction::SeatMasterBall { position } => self.control.seat_master(*position)?,
            OperatorInstruction::RemoveMasterBall => self.control.remove_master()?,
            // `vatcal sim-cell`'s tracker sees the nest SMR whenever the plate is placed
            OperatorInstruction::SeatNestSmr { .. }
            | OperatorInstruction::RemoveNestSmr
            | OperatorInstruction::ConfirmMotion { .. } => {}
        }
        self.log.push(instruction.to_string());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// A fake of the sim-cell control port (any number of connections).
    fn fake(answers: fn(&str) -> String) -> String {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = listener.local_addr().expect("addr").to_string();
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                let Ok(stream) = stream else { break };
                std::thread::spawn(move || {
                    let mut w = stream.try_clone().expect("clone");
                    for line in BufReader::new(stream).lines() {
                        let Ok(line) = line else { break };
                        if w.write_all(format!("{}\n", answers(&line)).as_bytes()).is_err() {
                            break;
                        }
                    }
                });
            }
        });
        addr
    }

    fn connect(addr: &str) -> SimControl {
        SimControl::connect(addr, Duration::from_secs(2), Duration::from_secs(2)).expect("connect")
    }

    #[test]
    fn place_and_placement_follow_the_line_protocol() {
        let addr = fake(|l| match l {
            "PLACEMENT?" => "PLACEMENT 2".into(),
            l => format!("OK {l}"),
        });
        let mut op = SimControlOperator::new(connect(&addr));
        op.perform(&OperatorInstruction::PlaceProbe { position: 3 }).expect("place");
        op.perform(&OperatorInstruction::RemoveMasterBall).expect("confirm");
        assert_eq!(op.control.placement().expect("placement"), Some(2));
        assert_eq!(op.log().len(), 2);
    }

    #[test]
    fn master_ball_instructions_are_sent_as_master_commands() {
        // the fake answers `OK <line>` only to the commands the operator must send
        let addr = fake(|l| match l {
            "PLACE 2" | "MASTER 2" | "MASTER OFF" => format!("OK {l}"),
            l => format!("ERR unexpected `{l}`"),
        });
        let mut op = SimControlOperator::new(connect(&addr));
        op.perform(&OperatorInstruction::PlaceProbe { position: 2 }).expect("place");
        op.perform(&OperatorInstruction::SeatMasterBall { position: 2 }).expect("seat the master ball");
        op.perform(&OperatorInstruction::RemoveMasterBall).expect("remove the master ball");
        op.perform(&OperatorInstruction::ConfirmMotion { description: "x".into() }).expect("confirm");
        assert_eq!(op.log().len(), 4);
        // a refusal (e.g. the plate is elsewhere) is an error naming the device, not logged
        let e = op.perform(&OperatorInstruction::SeatMasterBall { position: 3 }).expect_err("refused");
        assert!(e.to_string().starts_with("sim control: ") && e.to_string().contains("MASTER 3"), "{e}");
        assert_eq!(op.log().len(), 4);
    }

    #[test]
    fn the_clock_reads_the_cells_virtual_time() {
        let addr = fake(|l| match l {
            "TIME?" => "TIME 612.250000".into(),
            l => format!("ERR unexpected `{l}`"),
        });
        let clock = connect(&addr).clock().expect("clock");
        assert_eq!(clock.now(), Duration::from_millis(612_250));
        assert_eq!(clock.now_s(), 612.25);
        let addr = fake(|_| "TIME soon".into());
        let e = connect(&addr).time_s().expect_err("garbled");
        assert_eq!(e.kind(), ErrorKind::Protocol);
        assert!(e.to_string().contains("TIME soon"), "{e}");
    }

    #[test]
    fn the_temperature_is_read_with_temp() {
        let addr = fake(|l| match l {
            "TEMP?" => "TEMP 21.37".into(),
            l => format!("ERR unexpected `{l}`"),
        });
        let control = connect(&addr);
        let mut t = crate::SimCellThermometer::new(control.reconnect().expect("second connection"));
        use vatcal_hardware_traits::Thermometer;
        assert_eq!(t.read_c().expect("temperature"), 21.37);
        let addr = fake(|_| "TEMP NONE".into());
        let e = connect(&addr).temperature_c().expect_err("no channel");
        assert_eq!(e.kind(), ErrorKind::Disconnected);
        assert!(e.to_string().contains("no temperature channel"), "{e}");
        let addr = fake(|_| "TIME 3".into());
        assert_eq!(connect(&addr).temperature_c().expect_err("garbled").kind(), ErrorKind::Protocol);
    }

    #[test]
    fn a_wrong_answer_is_a_protocol_error_naming_the_device() {
        let addr = fake(|_| "ERR no such placement".into());
        let e = connect(&addr).place(9).expect_err("refused");
        assert_eq!(e.kind(), ErrorKind::Protocol);
        assert!(e.to_string().starts_with("sim control: ") && e.to_string().contains("ERR no such"), "{e}");
    }
}
