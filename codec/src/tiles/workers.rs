//! The threads tiles are coded on: a rayon pool of the requested size, or the calling
//! thread alone.
//!
//! Pools are kept for the life of the process, one per thread count: a caller coding a
//! large raster block by block (one call a block) reuses the same threads, and their
//! allocator arenas, instead of starting new ones for every block.

use std::ops::Range;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::{Arc, Mutex, PoisonError};

use rayon::prelude::*;

use crate::error::CodecError;

/// Runs per-tile work on `count` threads, results in tile order.
pub(crate) struct Workers {
    pool: Option<Arc<rayon::ThreadPool>>,
    count: usize,
}

/// The pools started so far, by thread count.
static POOLS: Mutex<Vec<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(Vec::new());

impl Workers {
    /// `threads` threads; 0 for one per core.
    pub(crate) fn new(threads: usize) -> Result<Workers, CodecError> {
        let count = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        let pool = (count > 1).then(|| shared_pool(count)).transpose()?;
        Ok(Workers { pool, count })
    }

    /// Threads the work runs on.
    pub(crate) fn count(&self) -> usize {
        self.count
    }

    /// `work(i)` for every `i` in `items`, in order of `i`.
    pub(crate) fn map<T: Send>(
        &self,
        items: Range<usize>,
        work: impl Fn(usize) -> T + Sync + Send,
    ) -> Vec<T> {
        match &self.pool {
            Some(pool) if items.len() > 1 => {
                pool.install(|| items.into_par_iter().map(work).collect())
            }
            _ => items.map(work).collect(),
        }
    }
}

/// Work handed to [`Workers::spawn`]: its result, once done.
pub(crate) struct Task<T>(Receiver<std::thread::Result<T>>);

impl<T> Task<T> {
    /// Waits for the result (a panic in the work resumes here).
    pub(crate) fn wait(self) -> T {
        match self
            .0
            .recv()
            .expect("a task sends its result before it ends")
        {
            Ok(result) => result,
            Err(panic) => resume_unwind(panic),
        }
    }
}

impl Workers {
    /// Starts `work` on the pool (tasks start in the order they are spawned), or runs it
    /// now on one thread.
    pub(crate) fn spawn<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Task<T> {
        let (result, task) = sync_channel(1);
        let run = move || {
            // The receiver may be gone (the decode stopped early): nothing to tell.
            let _ = result.send(catch_unwind(AssertUnwindSafe(work)));
        };
        match &self.pool {
            Some(pool) => pool.spawn_fifo(run),
            None => run(),
        }
        Task(task)
    }
}

/// The kept pool of `count` threads, started on first use.
fn shared_pool(count: usize) -> Result<Arc<rayon::ThreadPool>, CodecError> {
    let mut pools = POOLS.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, pool)) = pools.iter().find(|(n, _)| *n == count) {
        return Ok(Arc::clone(pool));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(count)
        .build()
        .map_err(|e| CodecError::InvalidParameters(format!("cannot start {count} threads: {e}")))?;
    let pool = Arc::new(pool);
    pools.push((count, Arc::clone(&pool)));
    Ok(pool)
}
