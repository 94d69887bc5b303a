//! Reply / event codes the driver and simulator refer to by name (§1.5, §1.9).

/// command buffer full
pub const BUFFER_FULL: u16 = 1000;
/// unknown or empty command
pub const UNKNOWN_COMMAND: u16 = 1001;
/// syntax error
pub const SYNTAX_ERROR: u16 = 1002;
/// wrong argument count or value out of range
pub const BAD_ARGUMENTS: u16 = 1003;
/// robot not activated
pub const NOT_ACTIVATED: u16 = 1005;
/// robot not homed
pub const NOT_HOMED: u16 = 1006;
/// joint over its limit
pub const JOINT_LIMIT: u16 = 1007;
/// robot is in error
pub const IN_ERROR: u16 = 1011;
/// linear move would cross a singularity
pub const SINGULARITY: u16 = 1012;
/// activation failed
pub const ACTIVATION_FAILED: u16 = 1013;
/// homing failed
pub const HOMING_FAILED: u16 = 1014;
/// pose out of reach
pub const OUT_OF_REACH: u16 = 1016;
/// mastering lost (not resettable)
pub const MASTERING_LOST: u16 = 1024;
/// error cannot be reset
pub const NOT_RESETTABLE: u16 = 1025;
/// motors activated
pub const ACTIVATED: u16 = 2000;
/// already activated (old firmware)
pub const ALREADY_ACTIVATED: u16 = 2001;
/// homing done
pub const HOMED: u16 = 2002;
/// already homed (old firmware)
pub const ALREADY_HOMED: u16 = 2003;
/// motors deactivated
pub const DEACTIVATED: u16 = 2004;
/// error reset
pub const ERROR_RESET: u16 = 2005;
/// there was no error to reset
pub const NO_ERROR_TO_RESET: u16 = 2006;
/// status word
pub const STATUS: u16 = 2007;
/// joints (legacy)
pub const JOINTS: u16 = 2026;
/// pose (legacy)
pub const POSE: u16 = 2027;
/// WRF
pub const WRF: u16 = 2013;
/// TRF
pub const TRF: u16 = 2014;
/// motion paused
pub const PAUSED: u16 = 2042;
/// motion resumed
pub const RESUMED: u16 = 2043;
/// motion cleared
pub const CLEARED: u16 = 2044;
/// end of movement events enabled / disabled
pub const EOM_ON: u16 = 2052;
/// end of movement events disabled
pub const EOM_OFF: u16 = 2053;
/// end of block events enabled
pub const EOB_ON: u16 = 2054;
/// end of block events disabled
pub const EOB_OFF: u16 = 2055;
/// firmware version
pub const FW_VERSION: u16 = 2081;
/// full firmware version
pub const FW_VERSION_FULL: u16 = 2082;
/// robot serial
pub const SERIAL: u16 = 2083;
/// product type
pub const PRODUCT_TYPE: u16 = 2084;
/// acknowledgement of `SetCtrlPortMonitoring` (our simulator's choice, see §1.4)
pub const CTRL_PORT_MONITORING: u16 = 2096;
/// `SyncCmdQueue` marker
pub const SYNC: u16 = 2097;
/// monitoring interval
pub const MONITORING_INTERVAL: u16 = 2116;
/// enabled real-time codes
pub const RT_MONITORING: u16 = 2117;
/// target joints with time stamp
pub const RT_TARGET_JOINTS: u16 = 2200;
/// target pose with time stamp
pub const RT_TARGET_CART: u16 = 2201;
/// measured joints with time stamp
pub const RT_JOINTS: u16 = 2210;
/// measured pose with time stamp
pub const RT_CART: u16 = 2211;
/// end of a monitoring cycle
pub const RT_CYCLE_END: u16 = 2230;
/// connection banner
pub const CONNECTED: u16 = 3000;
/// another user is connected
pub const ANOTHER_USER: u16 = 3001;
/// firmware update in progress
pub const FIRMWARE_UPDATE: u16 = 3002;
/// command too long / missing terminator
pub const COMMAND_TOO_LONG: u16 = 3003;
/// end of movement event
pub const EOM: u16 = 3004;
/// motion error
pub const MOTION_ERROR: u16 = 3005;
/// drive communication error
pub const DRIVE_COMM: u16 = 3006;
/// initialisation failed
pub const INIT_FAILED: u16 = 3009;
/// end of block event
pub const EOB: u16 = 3012;
/// maintenance check found a hardware problem
pub const MAINTENANCE: u16 = 3026;
/// internal error
pub const INTERNAL: u16 = 3027;
/// torque limit exceeded
pub const TORQUE_LIMIT: u16 = 3029;
/// checkpoint reached
pub const CHECKPOINT: u16 = 3030;
/// P-Stop 2 raised / cleared
pub const PSTOP2: u16 = 3032;
/// checkpoint discarded
pub const CHECKPOINT_DISCARDED: u16 = 3040;
/// reboot pending
pub const REBOOT_PENDING: u16 = 3053;
/// P-Stop 1 (newer firmware)
pub const PSTOP1: u16 = 3069;
/// E-Stop raised / cleared
pub const ESTOP: u16 = 3070;
