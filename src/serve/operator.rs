//! The lab page as the capture's operator (guided mode): the runner's change of stage becomes
//! an instruction on every page ("Place the black glossy sphere ..."), and the run goes on when
//! the controlling page answers with Continue for that very instruction (a late or doubled
//! click cannot skip the next one). While it waits, live preview frames keep coming, so the
//! person at the bench sees what they place.
//!
//! A stop request (pause, abort, the controlling page gone) ends the wait at once: the operator
//! returns and the runner's next safe point, right after it, ends the run with the light off.
//! Runs on the rig's thread, inside `run_session`; the instructions are the runner's own
//! (`stage_instructions`), the same the terminal prints.

use std::cell::Cell;
use std::rc::Rc;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::hub::Hub;
use super::live::LiveFeed;
use super::state::{Instruction, Phase};
use crate::capture::runner::stage_instructions;
use crate::capture::{CaptureError, Operator, Stage};

pub struct PageOperator<'a> {
    pub hub: Arc<Hub>,
    pub continues: &'a mpsc::Receiver<u64>,
    pub stop: Arc<AtomicBool>,
    pub live: &'a mut LiveFeed,
    /// Time spent waiting for the operator, shared with the progress (time left excludes it).
    pub waited: Rc<Cell<Duration>>,
    /// The number of the last instruction given.
    pub seq: u64,
}

impl Operator for PageOperator<'_> {
    fn set_stage(&mut self, from: Option<Stage>, to: Stage) -> Result<(), CaptureError> {
        let steps = stage_instructions(from, to);
        if steps.is_empty() {
            return Ok(());
        }
        self.seq += 1;
        let seq = self.seq;
        // a Continue that answered an earlier instruction must not answer this one
        while self.continues.try_recv().is_ok() {}
        // (the runner has logged the steps through the progress already)
        self.hub.update(|s| {
            if s.capture.phase != Phase::Stopping {
                s.capture.phase = Phase::Waiting;
            }
            s.capture.instruction = Some(Instruction {
                seq,
                steps: steps.clone(),
            });
        });
        let since = Instant::now();
        let outcome = loop {
            if self.stop.load(Ordering::SeqCst) {
                // the runner's safe point right after this ends the run
                break Ok(());
            }
            match self.continues.recv_timeout(
                self.live
                    .due_in()
                    .clamp(Duration::from_millis(5), Duration::from_millis(50)),
            ) {
                Ok(n) if n == seq => break Ok(()),
                Ok(_) | Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    break Err(CaptureError::Setup(
                        "the server stopped while waiting for the operator".into(),
                    ));
                }
            }
            self.live.tick();
        };
        self.waited.set(self.waited.get() + since.elapsed());
        self.hub.update(|s| {
            s.capture.instruction = None;
            if s.capture.phase == Phase::Waiting {
                s.capture.phase = Phase::Running;
            }
        });
        outcome
    }
}
