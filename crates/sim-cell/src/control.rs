//! The cell-control port: the simulated operator, driven over TCP (default port 55570).
//!
//! A line protocol (ASCII, one command per line, LF or CRLF; names case-insensitive), one
//! answer line per command:
//!
//! | command | answer | effect |
//! |---|---|---|
//! | `PLACE <n>` | `OK PLACE <n>` | the operator re-places the probe plate at calibration position `n` (takes the cell file's probe re-placement time ÷ the time scale) |
//! | `PLACEMENT?` | `PLACEMENT <n>` or `PLACEMENT NONE` | where the plate is |
//! | `MASTER <n>` | `OK MASTER <n>` | the operator seats the master ball in the probe (plate at `n`) |
//! | `MASTER OFF` | `OK MASTER OFF` | the operator removes the master ball |
//! | `TIME?` | `TIME <s>` | the cell's virtual time in seconds (motions, readings and re-placements so far, as the in-process cell counts them; independent of the time scale) |
//! | `TEMP?` | `TEMP <°C>` or `TEMP NONE` | what the cell's thermometer reads now (the temperature the truth's thermal drift sees at this virtual time, with the sensor's noise and 0.01 K resolution); `TEMP NONE` when the truth has no temperature channel (`--truth ideal`) |
//! | anything else, or a refused action | `ERR <reason>` | nothing |
//!
//! Several clients may be connected; each gets the answers to its own commands.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use vatcal_hardware_traits::sim_server::{Admission, Audience, ClientId, SimService};
use vatcal_hardware_traits::{Clock, Operator, OperatorInstruction, Thermometer};
use vatcal_sim::VirtualCell;

/// Longest accepted line; a longer one is answered `ERR` and discarded.
const MAX_LINE: usize = 256;

/// The cell-control protocol on the virtual cell.
pub struct ControlService {
    cell: VirtualCell,
    time_scale: f64,
    buffers: HashMap<u64, Vec<u8>>,
    /// puts the world where the motion simulators are (their motions onto the virtual clock)
    sync: Option<Arc<dyn Fn() + Send + Sync>>,
}

impl std::fmt::Debug for ControlService {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControlService")
            .field("time_scale", &self.time_scale)
            .field("sync", &self.sync.is_some())
            .finish_non_exhaustive()
    }
}

impl ControlService {
    /// The operator of `cell`; actions take their time ÷ `time_scale` of wall-clock time.
    pub fn new(cell: VirtualCell, time_scale: f64) -> Self {
        Self { cell, time_scale, buffers: HashMap::new(), sync: None }
    }

    /// `sync` is called before the time is read (`TIME?`): it puts the world where the
    /// external motion simulators are, so their motions are on the virtual clock.
    pub fn with_sync(mut self, sync: Arc<dyn Fn() + Send + Sync>) -> Self {
        self.sync = Some(sync);
        self
    }

    /// Answers one command line (without its terminator).
    pub fn answer(&mut self, line: &str) -> String {
        let words: Vec<&str> = line.split_whitespace().collect();
        let upper: Vec<String> = words.iter().map(|w| w.to_ascii_uppercase()).collect();
        let upper: Vec<&str> = upper.iter().map(String::as_str).collect();
        match upper.as_slice() {
            ["PLACE", _] => match parse_position(words[1]) {
                Ok(position) => {
                    let wait = self.cell.config().timing.operator_s / self.time_scale;
                    match self.cell.operator().perform(&OperatorInstruction::PlaceProbe { position }) {
                        Ok(()) => {
                            std::thread::sleep(Duration::try_from_secs_f64(wait).unwrap_or(Duration::ZERO));
                            format!("OK PLACE {position}")
                        }
                        Err(e) => format!("ERR {}", e.message()),
                    }
                }
                Err(reason) => format!("ERR {reason}"),
            },
            ["TIME?"] => {
                if let Some(sync) = &self.sync {
                    sync();
                }
                format!("TIME {:.6}", self.cell.clock().now().as_secs_f64())
            }
            ["TEMP?"] => {
                if let Some(sync) = &self.sync {
                    sync();
                }
                match self.cell.thermometer().map(|mut t| t.read_c()) {
                    None => "TEMP NONE".to_owned(),
                    Some(Ok(c)) => format!("TEMP {c:.3}"),
                    Some(Err(e)) => format!("ERR {}", e.message()),
                }
            }
            ["PLACEMENT?"] => match self.cell.plate_position() {
                Some(n) => format!("PLACEMENT {n}"),
                None => "PLACEMENT NONE".to_owned(),
            },
            ["MASTER", "OFF"] => match self.cell.operator().perform(&OperatorInstruction::RemoveMasterBall) {
                Ok(()) => "OK MASTER OFF".to_owned(),
                Err(e) => format!("ERR {}", e.message()),
            },
            ["MASTER", _] => match parse_position(words[1]) {
                Ok(position) => {
                    match self.cell.operator().perform(&OperatorInstruction::SeatMasterBall { position }) {
                        Ok(()) => format!("OK MASTER {position}"),
                        Err(e) => format!("ERR {}", e.message()),
                    }
                }
                Err(reason) => format!("ERR {reason}"),
            },
            [] => "ERR empty command".to_owned(),
            _ => format!(
                "ERR unknown command '{}' (PLACE <n>, PLACEMENT?, MASTER <n>, MASTER OFF, TIME?, TEMP?)",
                line.trim()
            ),
        }
    }
}

fn parse_position(word: &str) -> Result<u32, String> {
    word.parse::<u32>().map_err(|_| format!("'{word}' is not a calibration position number"))
}

impl SimService for ControlService {
    fn connect(&mut self, client: ClientId) -> Admission {
        self.buffers.insert(client.id, Vec::new());
        Admission::Accept(Vec::new())
    }

    fn input(&mut self, client: ClientId, bytes: &[u8]) -> Vec<(Audience, Vec<u8>)> {
        let mut buffer = self.buffers.remove(&client.id).unwrap_or_default();
        buffer.extend_from_slice(bytes);
        let mut out = Vec::new();
        while let Some(end) = buffer.iter().position(|b| *b == b'\n') {
            let line: Vec<u8> = buffer.drain(..=end).collect();
            let text = String::from_utf8_lossy(&line[..end]);
            let answer = self.answer(text.trim_end_matches('\r'));
            out.push((Audience::Client(client), format!("{answer}\n").into_bytes()));
        }
        if buffer.len() > MAX_LINE {
            buffer.clear();
            out.push((
                Audience::Client(client),
                format!("ERR line longer than {MAX_LINE} bytes\n").into_bytes(),
            ));
        }
        self.buffers.insert(client.id, buffer);
        out
    }

    fn disconnected(&mut self, client: ClientId) {
        self.buffers.remove(&client.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::CellFile;
    use vatcal_kinematics::Model;

    fn service() -> ControlService {
        let cell = CellFile::from_toml_str(crate::BUILT_IN_CELL, "built-in").expect("cell");
        let nominal = Model::from_cell(&cell).expect("model");
        ControlService::new(VirtualCell::paper(nominal, 1), 1e6)
    }

    #[test]
    fn places_reports_and_refuses() {
        let mut s = service();
        assert_eq!(s.answer("PLACEMENT?"), "PLACEMENT NONE");
        let first = s.cell.nominal().position_ids()[0];
        assert_eq!(s.answer(&format!("place {first}")), format!("OK PLACE {first}"));
        assert_eq!(s.answer("Placement?"), format!("PLACEMENT {first}"));
        assert_eq!(s.cell.plate_position(), Some(first));
        assert!(s.answer("PLACE 999").starts_with("ERR there is no calibration position 999"));
        assert!(s.answer("PLACE x").starts_with("ERR 'x' is not"));
        assert!(s.answer("DANCE").starts_with("ERR unknown command 'DANCE'"));
        assert_eq!(s.answer(&format!("MASTER {first}")), format!("OK MASTER {first}"));
        assert_eq!(s.answer("MASTER OFF"), "OK MASTER OFF");
        assert!(s.answer("MASTER 999").starts_with("ERR"));
        // one re-placement's worth of virtual time (the operator's), whatever the time scale
        let operator_s = s.cell.config().timing.operator_s;
        assert_eq!(s.answer("TIME?"), format!("TIME {:.6}", operator_s));
    }

    #[test]
    fn temp_reads_the_cells_thermometer() {
        // the built-in ideal truth has no temperature channel
        let mut s = service();
        assert_eq!(s.answer("TEMP?"), "TEMP NONE");
        let cell = CellFile::from_toml_str(crate::BUILT_IN_CELL, "built-in").expect("cell");
        let nominal = Model::from_cell(&cell).expect("model");
        let cell = vatcal_sim::truth::TruthSpec::PaperLike.virtual_cell(nominal, 1).expect("paper-like");
        let profile = cell.config().physics.thermal.expect("temperature channel");
        let mut s = ControlService::new(cell, 1e6);
        let first = s.cell.nominal().position_ids()[0];
        s.answer(&format!("PLACE {first}"));
        let answer = s.answer("temp?");
        let t: f64 = answer.strip_prefix("TEMP ").and_then(|t| t.parse().ok()).expect(&answer);
        let truth = profile.at(s.cell.clock().now().as_secs_f64());
        assert!((t - truth).abs() < 0.1, "{answer} vs the cell's {truth} °C");
    }

    #[test]
    fn lines_are_framed_per_client() {
        let mut s = service();
        let a = ClientId { id: 1, listener: 0 };
        let b = ClientId { id: 2, listener: 0 };
        s.connect(a);
        s.connect(b);
        assert!(s.input(a, b"PLACEM").is_empty());
        let out = s.input(b, b"FOO\r\n");
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].0, Audience::Client(b));
        let out = s.input(a, b"ENT?\n");
        assert_eq!(out[0].1, b"PLACEMENT NONE\n");
        let out = s.input(a, &[b'x'; MAX_LINE + 1]);
        assert!(String::from_utf8_lossy(&out[0].1).starts_with("ERR line longer"));
    }
}
