//! Time, injected: real hardware runs on [`SystemClock`], simulators and tests on
//! [`VirtualClock`], which only advances when somebody sleeps on it, so a 25-minute simulated
//! campaign runs in milliseconds and every time stamp is reproducible.

use std::fmt::Debug;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// A source of time that callers can also sleep on.
///
/// Implementation: `now` must be monotonic for the lifetime of the clock; `sleep(d)` must
/// return after `now` advanced by at least `d`.
pub trait Clock: Send + Sync + Debug {
    /// Time elapsed since the clock's epoch.
    fn now(&self) -> Duration;
    /// Blocks (real clock) or advances time (virtual clock) by `duration`.
    fn sleep(&self, duration: Duration);

    /// `now` in seconds (f64).
    fn now_s(&self) -> f64 {
        self.now().as_secs_f64()
    }
}

/// Wall-clock time: the epoch is the Unix epoch, so `now` keeps counting across process
/// restarts (a resumed campaign sees the real gap). `sleep` is `std::thread::sleep`.
#[derive(Debug, Clone, Copy, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now(&self) -> Duration {
        SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO)
    }

    fn sleep(&self, duration: Duration) {
        std::thread::sleep(duration);
    }
}

/// Simulated time with nanosecond resolution. Clones share the same time, so every simulated
/// device and the campaign see one clock. `sleep` advances time instantly.
#[derive(Debug, Clone, Default)]
pub struct VirtualClock {
    nanos: Arc<AtomicU64>,
}

impl VirtualClock {
    /// A clock at time zero.
    pub fn new() -> Self {
        Self::default()
    }

    /// A clock starting at `start`.
    pub fn starting_at(start: Duration) -> Self {
        let c = Self::new();
        c.advance(start);
        c
    }

    /// Advances the time by `d`.
    pub fn advance(&self, d: Duration) {
        let add = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        let _ = self.nanos.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| Some(n.saturating_add(add)));
    }

    /// Moves the time forward to `t` (no effect if the clock is already past `t`).
    pub fn advance_to(&self, t: Duration) {
        let target = u64::try_from(t.as_nanos()).unwrap_or(u64::MAX);
        self.nanos.fetch_max(target, Ordering::SeqCst);
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> Duration {
        Duration::from_nanos(self.nanos.load(Ordering::SeqCst))
    }

    fn sleep(&self, duration: Duration) {
        self.advance(duration);
    }
}

impl<C: Clock + ?Sized> Clock for Arc<C> {
    fn now(&self) -> Duration {
        (**self).now()
    }
    fn sleep(&self, duration: Duration) {
        (**self).sleep(duration)
    }
}

impl<C: Clock + ?Sized> Clock for &C {
    fn now(&self) -> Duration {
        (**self).now()
    }
    fn sleep(&self, duration: Duration) {
        (**self).sleep(duration)
    }
}

impl<C: Clock + ?Sized> Clock for Box<C> {
    fn now(&self) -> Duration {
        (**self).now()
    }
    fn sleep(&self, duration: Duration) {
        (**self).sleep(duration)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn virtual_clock_is_shared_and_monotonic() {
        let c = VirtualClock::new();
        let d: Arc<dyn Clock> = Arc::new(c.clone());
        d.sleep(Duration::from_millis(1500));
        assert_eq!(c.now(), Duration::from_millis(1500));
        c.advance_to(Duration::from_secs(1));
        assert_eq!(c.now(), Duration::from_millis(1500), "never goes back");
        c.advance_to(Duration::from_secs(3));
        assert!((d.now_s() - 3.0).abs() < 1e-12);
        assert_eq!(VirtualClock::starting_at(Duration::from_secs(7)).now(), Duration::from_secs(7));
    }

    #[test]
    fn system_clock_counts_from_the_unix_epoch() {
        let c = SystemClock;
        assert!(c.now() > Duration::from_secs(1_600_000_000));
    }
}
