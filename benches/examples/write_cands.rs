//! TEMPORARY: writes probe candidate poses to a CSV (to be removed).
use vatcal_core::CellFile;
use vatcal_kinematics::Model;
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(3300);
    let seed: u64 = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/meca500-zaber.toml")).unwrap();
    let model = Model::from_cell(&cell).unwrap();
    let poses = vatcal_sim::truth::probe_start_poses(&model, n, seed);
    println!("position,tcp,q1,q2,q3,q4,q5,q6,q7");
    for m in poses {
        let q: Vec<String> = m.q.to_mm_deg().iter().map(|v| v.to_string()).collect();
        println!("{},{},{}", m.position().unwrap(), m.tcp, q.join(","));
    }
}
