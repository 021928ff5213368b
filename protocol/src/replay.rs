//! Retries on a noisy line: a host that got no reply sends the same request again with
//! the same `seq`; the handler answers it with the reply it gave the first time instead of
//! carrying the request out twice (a `Move` or `SetStiffness` repeated would be harmless,
//! an `Enable` after a fault was cleared in between would not, and counters would be off).
//!
//! Only the last request is remembered: the host waits for one reply at a time, so a retry
//! always repeats the last request the board received. A different request with a reused
//! `seq` (the host's counter wrapped) is carried out as usual.

use crate::frame::Frame;
use crate::msg::{Reply, Request};
use crate::NO_SEQ;

/// The last request carried out and its reply.
#[derive(Clone, Debug, Default)]
pub struct ReplyCache {
    last: Option<(u16, Request, Reply)>,
    replayed: u32,
}

impl ReplyCache {
    /// An empty cache.
    #[must_use]
    pub const fn new() -> Self {
        ReplyCache {
            last: None,
            replayed: 0,
        }
    }

    /// The reply already given to `frame`, if it repeats the last request.
    pub fn replay(&mut self, frame: &Frame<Request>) -> Option<Frame<Reply>> {
        match &self.last {
            Some((seq, req, reply)) if *seq == frame.seq && *req == frame.body => {
                self.replayed = self.replayed.saturating_add(1);
                Some(Frame::new(*seq, *reply))
            }
            _ => None,
        }
    }

    /// Remembers the reply to `request` (frames without a trustworthy `seq` are not kept).
    pub fn keep(&mut self, seq: u16, request: Request, reply: Reply) {
        self.last = (seq != NO_SEQ).then_some((seq, request, reply));
    }

    /// Repeated requests answered from the cache, since start (saturating).
    #[must_use]
    pub const fn replayed(&self) -> u32 {
        self.replayed
    }
}
