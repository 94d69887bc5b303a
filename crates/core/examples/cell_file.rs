//! Reading a cell file and the core types every other crate uses.
//!
//! Loads the canonical cell (`fixtures/meca500-zaber.toml`), prints its MDH rows, loads a
//! version-2 cell of another robot (`fixtures/ur5e.toml`), converts joint vectors between file
//! units (mm, degrees) and internal units (mm, radians), lists the
//! paper's 34 parameters by name, and shows the error a broken file gives.
//!
//! ```text
//! cargo run -p vatcal-core --example cell_file
//! ```

use vatcal_core::{CellFile, Frame, JointVector, ParamId, ParamSet};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml");
    let cell = CellFile::load(path)?;
    println!("{path}: format {} v{}, {} joint rows", cell.format, cell.version, cell.joints.len());
    for j in &cell.joints {
        println!(
            "  row {} {:>8} {:<10} alpha {:>6.1} deg  a {:>6.1} mm  theta {:>6.1} deg  d {:>6.1} mm",
            j.index,
            format!("{:?}", j.name),
            format!("{:?}", j.kind),
            j.alpha_deg,
            j.a_mm,
            j.theta_deg,
            j.d_mm
        );
    }
    println!("TCP ids {:?}, calibration positions {:?}", cell.tcp_ids(), cell.position_ids());

    // version 2: any serial chain (here a 6R arm without a guide)
    let ur5e = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/ur5e.toml"))?;
    println!("ur5e.toml: format {} v{}, joint kinds {:?}", ur5e.format, ur5e.version, ur5e.joint_kinds());
    let q6 = JointVector::from_file_units(&[0.0, -90.0, 90.0, -90.0, -90.0, 0.0], &ur5e.joint_kinds())?;
    println!("a UR5e joint vector: {} values, q2 = {:.6} rad", q6.len(), q6.get(2));

    // file units (q1 mm, q2..q7 deg) <-> internal units (mm, rad)
    let q = JointVector::from_mm_deg(150.0, [10.0, 20.0, -30.0, 40.0, 50.0, 60.0]);
    println!("q2 = {:.6} rad internally; back in file units: {:?}", q.get(2), q.to_mm_deg());
    assert!((q.to_mm_deg()[2] - 20.0).abs() < 1e-12, "q3 round-trips through radians");

    // parameter names are stable strings (reports, cell-file effect values, CLI --params)
    let paper34 = ParamSet::paper34();
    println!("paper34: {} parameters: {}", paper34.len(), paper34.names().join(" "));
    let id = ParamId::from_name("theta_offset_3").ok_or("theta_offset_3 is a parameter name")?;
    println!("`theta_offset_3` parses to {id:?}, unit {:?}", id.unit());

    // a rigid transform
    let f = Frame::identity();
    println!(
        "identity frame maps (1,2,3) to {:?}",
        f.transform_point(&nalgebra::Vector3::new(1.0, 2.0, 3.0)).as_slice()
    );

    // a bad file gives an error naming the field
    let text = std::fs::read_to_string(path)?.replacen("version = 1", "version = 99", 1);
    match CellFile::from_toml_str(&text, "broken.toml") {
        Ok(_) => return Err("a version-99 file must be refused".into()),
        Err(e) => println!("refused as expected: {e}"),
    }
    Ok(())
}
