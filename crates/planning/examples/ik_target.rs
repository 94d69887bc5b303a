//! Inverse kinematics of a target: every joint solution that puts TCP 2 on a world point with
//! the tool pointing down, at three guide positions of the canonical cell.
//!
//! [`ToolPoseIk`] seeds a Levenberg–Marquardt refinement on the full model with the closed-form
//! solutions of the nominal Meca500 (up to eight branches per guide position). Each solution is
//! checked by forward kinematics and against the joint limits.
//!
//! ```text
//! cargo run -p vatcal-planning --example ik_target
//! ```

use nalgebra::{Matrix3, Vector3};
use vatcal_core::CellFile;
use vatcal_kinematics::Model;
use vatcal_planning::ik::{RefineOptions, ToolPoseIk, rotation_angle_between, tool_pose_for_tcp};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell = CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-zaber.toml"))?;
    let model = Model::from_cell(&cell)?;
    let tcp = 2;
    let tcp_in_tool = model.tcp(tcp).ok_or("the canonical cell has TCP 2")?;
    // tool z axis pointing down (rotation of pi about world x), TCP at this world point
    let down = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let point = Vector3::new(60.0, -40.0, 40.0);
    let target = tool_pose_for_tcp(&down, &tcp_in_tool, &point);

    let ik = ToolPoseIk::new(&model, RefineOptions::default())?;
    let solutions = ik.solve(&[50.0, 150.0, 250.0], &target);
    println!("{} solutions for TCP {tcp} at {:?} mm, tool pointing down", solutions.len(), point.as_slice());
    if solutions.is_empty() {
        return Err("the target is reachable; IK must find a solution".into());
    }
    for q in &solutions {
        let tool = model.chain(q).tool;
        let p = model.tcp_position(q, tcp)?;
        let within = model.limit_violation(q).is_none();
        println!(
            "  q = {:8.3?} | TCP error {:.1e} mm, tool rotation error {:.1e} rad, within limits: {within}",
            q.to_mm_deg(),
            (p - point).norm(),
            rotation_angle_between(&tool.r, &target.r)
        );
        if (p - point).norm() > 1e-8 {
            return Err("an IK solution misses the target".into());
        }
    }
    Ok(())
}
