//! Zaber X-LRQ300AP driver (work in progress).
