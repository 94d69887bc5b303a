"""Vendor clients against `vatcal sim-cell` (run through scripts/interop/run.sh).

Starts `vatcal sim-cell` on ephemeral loopback ports, then:
  * mecademicpy 3.0.3: Connect, ActivateRobot/WaitActivated, Home/WaitHomed, SetJointVel,
    MoveJoints, WaitIdle, GetRtTargetJointPos (target read back to < 1e-3 deg), a MoveJoints
    outside J1's limit is refused (WaitIdle raises) and ResetError/ResumeMotion recover;
  * zaber-motion 10.2.0: Connection.open_tcp, detect_devices(identify_devices=False), axis
    home, move_absolute and get_position in native units (microsteps).
Prints one line per step; exits non-zero at the first failure.
"""

import subprocess
import sys
import time

TIMEOUT_S = 30.0


def step(name):
    print(f"interop: {name}", flush=True)


def start_sim_cell(binary):
    args = [binary, "sim-cell", "--bind", "127.0.0.1", "--seed", "1", "--time-scale", "20"]
    for flag in ("--meca500-control-port", "--meca500-monitoring-port", "--zaber-port",
                 "--gauge1-port", "--gauge2-port", "--gauge3-port", "--control-port", "--tracker-port"):
        args += [flag, "0"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
    ports = {}
    while len(ports) < 8:
        line = proc.stdout.readline()
        if not line:
            raise RuntimeError(f"vatcal sim-cell exited early (status {proc.wait()})")
        words = line.split()
        if len(words) == 3 and words[0] == "listening":
            host, port = words[2].rsplit(":", 1)
            ports[words[1]] = (host, int(port))
    return proc, ports


def mecademicpy_sequence(host, port):
    import mecademicpy.robot as mdr

    robot = mdr.Robot()
    step(f"mecademicpy {mdr.__name__}: Connect {host}:{port}")
    robot.Connect(address=f"{host}:{port}", disconnect_on_exception=False, timeout=5.0)
    try:
        step("mecademicpy: ActivateRobot / WaitActivated")
        robot.ActivateRobot()
        robot.WaitActivated(timeout=TIMEOUT_S)
        step("mecademicpy: Home / WaitHomed")
        robot.Home()
        robot.WaitHomed(timeout=TIMEOUT_S)
        step("mecademicpy: SetJointVel, MoveJoints, WaitIdle")
        target = [10.0, -20.0, 30.0, 5.0, 40.0, 15.0]
        robot.SetJointVel(50)
        robot.MoveJoints(*target)
        robot.WaitIdle(timeout=TIMEOUT_S)
        step("mecademicpy: GetRtTargetJointPos")
        q = robot.GetRtTargetJointPos()
        worst = max(abs(a - b) for a, b in zip(q, target))
        if len(q) != 6 or worst >= 1e-3:
            raise AssertionError(f"read back {q} for target {target} (worst {worst} deg)")
        print(f"interop: mecademicpy read back the target to {worst:.1e} deg", flush=True)

        step("mecademicpy: MoveJoints outside J1's limit is refused")
        robot.MoveJoints(200.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        refused = False
        try:
            robot.WaitIdle(timeout=TIMEOUT_S)
        except Exception as e:  # mecademicpy raises InterruptException on the robot's error
            refused = True
            print(f"interop: WaitIdle raised {type(e).__name__}: {e}", flush=True)
        if not refused:
            raise AssertionError("WaitIdle did not raise after a move beyond J1's limit")
        if not robot.GetStatusRobot(synchronous_update=True).error_status:
            raise AssertionError("the robot is not in error after the refused move")

        step("mecademicpy: ResetError / ResumeMotion recover")
        robot.ResetError()
        robot.ResumeMotion()
        deadline = time.monotonic() + TIMEOUT_S
        while robot.GetStatusRobot(synchronous_update=True).error_status:
            if time.monotonic() > deadline:
                raise AssertionError("still in error after ResetError")
            time.sleep(0.05)
        robot.MoveJoints(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        robot.WaitIdle(timeout=TIMEOUT_S)
        q = robot.GetRtTargetJointPos()
        if max(abs(v) for v in q) >= 1e-3:
            raise AssertionError(f"after recovery the robot is at {q}, not at zero")
    finally:
        robot.Disconnect()


def zaber_sequence(host, port):
    from zaber_motion import Units
    from zaber_motion.ascii import Connection

    step(f"zaber-motion: Connection.open_tcp {host}:{port}")
    with Connection.open_tcp(host, port) as connection:
        step("zaber-motion: detect_devices(identify_devices=False)")
        devices = connection.detect_devices(identify_devices=False)
        if len(devices) != 1:
            raise AssertionError(f"expected one device, found {len(devices)}")
        axis = devices[0].get_axis(1)
        step("zaber-motion: home")
        axis.home()
        position = axis.get_position(Units.NATIVE)
        if position != 0:
            raise AssertionError(f"homed at {position} microsteps, not 0")
        step("zaber-motion: move_absolute / get_position (native units)")
        target = 614_400  # 120 mm at 2.5 mm / 12 800 microsteps
        axis.move_absolute(target, Units.NATIVE)
        position = axis.get_position(Units.NATIVE)
        if position != target:
            raise AssertionError(f"at {position} microsteps after a move to {target}")
        print(f"interop: zaber-motion read back {position} microsteps", flush=True)


def main():
    if len(sys.argv) != 2:
        print("usage: interop.py PATH/TO/vatcal", file=sys.stderr)
        return 2
    proc, ports = start_sim_cell(sys.argv[1])
    try:
        mecademicpy_sequence(*ports["meca500-control"])
        zaber_sequence(*ports["zaber"])
    finally:
        proc.terminate()
        try:
            status = proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise RuntimeError("vatcal sim-cell did not stop on SIGTERM")
    if status != 0:
        print(f"interop: vatcal sim-cell exited with status {status}", file=sys.stderr)
        return 1
    print("interop: 2 passed, 0 failed", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
