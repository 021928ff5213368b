//! What the service tests share.

use service::Actuator;

/// The host's stand-in for an RTIC shared resource: `lock` hands out the actuator.
pub struct Cell(pub Actuator);

impl rtic_core::Mutex for Cell {
    type T = Actuator;
    fn lock<R>(&mut self, f: impl FnOnce(&mut Actuator) -> R) -> R {
        f(&mut self.0)
    }
}
