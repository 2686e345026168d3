//! P_R's commands as P_I reads them. A command that a preemption check
//! takes early (a fetch command during a prefetch read) is kept for the
//! command loop; a settle request ([`Cmd::Settle`]) preempts nothing: it is
//! kept aside and answered when P_I next runs out of work.

use std::time::Duration;

use crossbeam_channel::{Receiver, RecvError, RecvTimeoutError, Sender, TryRecvError};

use crate::runtime::protocol::Cmd;

/// How often P_I, waiting for the next fetch command with nothing it may
/// start in time, looks again whether requests started ahead have answered.
pub(super) const READY_POLL: Duration = Duration::from_millis(2);

pub(super) struct Inbox {
    rx: Receiver<Cmd>,
    pending: Option<Cmd>,
    settle: Option<Sender<()>>,
}

impl Inbox {
    pub(super) fn new(rx: Receiver<Cmd>) -> Self {
        Self {
            rx,
            pending: None,
            settle: None,
        }
    }

    /// A command taken early is waiting for the command loop.
    pub(super) fn waiting(&self) -> bool {
        self.pending.is_some()
    }

    /// Whether a new command has arrived (it is kept for the loop); a
    /// settle request is not one.
    pub(super) fn preempted(&mut self) -> bool {
        if self.pending.is_none()
            && let Ok(c) = self.try_recv()
        {
            self.pending = Some(c);
            return true;
        }
        false
    }

    /// The next command without waiting: the one taken early, else the
    /// channel's.
    pub(super) fn try_recv(&mut self) -> Result<Cmd, TryRecvError> {
        if let Some(c) = self.pending.take() {
            return Ok(c);
        }
        loop {
            match self.rx.try_recv()? {
                Cmd::Settle(s) => self.settle = Some(s),
                c => return Ok(c),
            }
        }
    }

    /// The next command, waiting at most `poll` for it (`None`: as long as
    /// it takes); `Ok(None)` when nothing came in that time. P_I has
    /// nothing else to do, so a settle request, kept or arriving, is
    /// answered first.
    pub(super) fn recv_within(&mut self, poll: Option<Duration>) -> Result<Option<Cmd>, RecvError> {
        if let Some(c) = self.pending.take() {
            return Ok(Some(c));
        }
        loop {
            if let Some(s) = self.settle.take() {
                let _ = s.send(());
            }
            let c = match poll {
                None => self.rx.recv()?,
                Some(d) => match self.rx.recv_timeout(d) {
                    Ok(c) => c,
                    Err(RecvTimeoutError::Timeout) => return Ok(None),
                    Err(RecvTimeoutError::Disconnected) => return Err(RecvError),
                },
            };
            match c {
                Cmd::Settle(s) => self.settle = Some(s),
                c => return Ok(Some(c)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crossbeam_channel::bounded;

    #[test]
    fn a_settle_request_preempts_nothing_and_is_answered_when_idle() {
        let (tx, rx) = bounded(4);
        let mut inbox = Inbox::new(rx);
        let (stx, srx) = bounded(1);
        tx.send(Cmd::Settle(stx)).unwrap();
        assert!(!inbox.preempted(), "a settle request is no new command");
        assert!(srx.try_recv().is_err(), "not answered while there is work");
        tx.send(Cmd::Unusable(3)).unwrap();
        assert!(inbox.preempted());
        assert!(inbox.waiting());
        assert!(matches!(inbox.try_recv(), Ok(Cmd::Unusable(3))));
        // Idle: the request is answered before waiting for the next command.
        tx.send(Cmd::Shutdown).unwrap();
        assert!(matches!(inbox.recv_within(None), Ok(Some(Cmd::Shutdown))));
        assert!(srx.try_recv().is_ok());
    }
}
