//! The threads tiles are coded on: a rayon pool of the requested size, or the calling
//! thread alone.

use std::ops::Range;

use rayon::prelude::*;

use crate::error::CodecError;

/// Runs per-tile work on `count` threads, results in tile order.
pub(crate) struct Workers {
    pool: Option<rayon::ThreadPool>,
    count: usize,
}

impl Workers {
    /// `threads` threads; 0 for one per core.
    pub(crate) fn new(threads: usize) -> Result<Workers, CodecError> {
        let count = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        let pool = (count > 1)
            .then(|| rayon::ThreadPoolBuilder::new().num_threads(count).build())
            .transpose()
            .map_err(|e| {
                CodecError::InvalidParameters(format!("cannot start {count} threads: {e}"))
            })?;
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
