//! What P_R and P_I say to each other over their bounded channels.

use std::sync::Arc;

use crate::camera::View;
use crate::metrics::LoaderCounters;
use crate::skeleton::RepId;

/// P_R → P_I.
pub(super) enum Cmd {
    Fetch {
        /// Boxed: a view with its section is the largest part of a command.
        view: Box<View>,
        turn_rad: f32,
        front: Arc<Vec<RepId>>,
        /// Reps of the view's front that occlusion culling left out.
        hidden: Arc<Vec<RepId>>,
        /// The tolerance the front was computed for (the governor's).
        tolerance_px: f32,
        /// Reps P_R draws fading out (`crate::fade`): P_I hands over and
        /// pins those resident, before the front.
        fading: Arc<Vec<RepId>>,
    },
    /// P_R cannot use this rep (a view-dependence tree whose store failed).
    Unusable(RepId),
    /// Answer on the sender once P_I has nothing more to do before the
    /// next fetch command (nothing queued, or its pacing says wait): on a
    /// simulated clock a paced walk waits for it instead of sleeping.
    Settle(crossbeam_channel::Sender<()>),
    Shutdown,
}

/// Draw `rep` for front rep `for_rep` (an ancestor when they differ).
pub(super) struct Draw {
    pub(super) rep: RepId,
    pub(super) for_rep: RepId,
    pub(super) payload: Arc<[u8]>,
}

/// P_I → P_R.
pub(super) enum Reply {
    /// Front reps to draw (resident ones, those Stage II read, ancestors
    /// in place of others), grouped (`loader::outbox`): P_I goes on
    /// reading and prefetching while P_R draws them, instead of waiting on
    /// the channel for P_R to take them one by one.
    Draws(Vec<Draw>),
    /// The fading-out reps still resident (before any other draw).
    Fading(Vec<Draw>),
    /// Nothing resident can stand in for `for_rep` (only without a root rep).
    Missing,
    /// P_I evicted these reps (sent before any later draw).
    Evicted(Vec<RepId>),
    /// Stage II is over.
    Done(LoaderCounters),
}
