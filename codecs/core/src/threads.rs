//! One handle to the worker threads a caller lends to encoders and decoders.
//!
//! The caller builds a [`ThreadPool`] once (the CLI from `--threads`, a batch tool per job) and
//! passes it down through [`EncodeSettings`](crate::EncodeSettings) and
//! [`DecodeOptions`](crate::DecodeOptions). Codecs never build pools of their own and never use
//! rayon's global pool behind the caller's back: parallel work goes through
//! [`ThreadPool::map`] / [`ThreadPool::for_each_chunk_mut`], which run on the caller's thread
//! when the handle is single-threaded. Nested use (a container decoding its tiles in parallel,
//! each tile's codec asking the same handle for parallelism) stays on the one pool: rayon runs
//! the inner work on the same workers instead of starting new threads.

use crate::{Error, Result};
use rayon::prelude::*;
use std::sync::Arc;

/// Worker threads for encoding and decoding: none (the calling thread only, the default) or a
/// shared rayon pool. Cloning shares the pool.
#[derive(Clone, Default)]
pub struct ThreadPool {
    pool: Option<Arc<rayon::ThreadPool>>,
}

impl std::fmt::Debug for ThreadPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ThreadPool({} threads)", self.threads())
    }
}

impl PartialEq for ThreadPool {
    /// Two handles are equal when they run on the same pool (or both on the caller's thread).
    fn eq(&self, other: &Self) -> bool {
        match (&self.pool, &other.pool) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}
impl Eq for ThreadPool {}

impl ThreadPool {
    /// The calling thread only: no worker threads are started.
    pub fn single() -> Self {
        ThreadPool { pool: None }
    }

    /// A pool of `threads` workers; 0 means one per available core. One thread gives
    /// [`ThreadPool::single`] (no pool at all).
    pub fn new(threads: usize) -> Result<Self> {
        let threads = if threads == 0 { available_cores() } else { threads };
        if threads <= 1 {
            return Ok(Self::single());
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("hdrcodec-{i}"))
            .build()
            .map_err(|e| Error::Io(std::io::Error::other(format!("cannot start {threads} worker threads: {e}"))))?;
        Ok(ThreadPool { pool: Some(Arc::new(pool)) })
    }

    /// A handle on an existing rayon pool (an application's own).
    pub fn from_rayon(pool: Arc<rayon::ThreadPool>) -> Self {
        ThreadPool { pool: Some(pool) }
    }

    /// The rayon pool behind this handle, `None` for [`ThreadPool::single`]: for libraries that
    /// take a rayon pool of their own (rav1e's `Config::with_thread_pool`), so that they run on
    /// the caller's workers instead of starting theirs.
    pub fn rayon_pool(&self) -> Option<&Arc<rayon::ThreadPool>> {
        self.pool.as_ref()
    }

    /// How many threads work run through this handle may use (1 for [`ThreadPool::single`]).
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.current_num_threads())
    }

    /// True when work may run on more than one thread.
    pub fn is_parallel(&self) -> bool {
        self.threads() > 1
    }

    /// Runs `f` inside the pool (so that rayon work it starts uses these workers), or directly
    /// on the calling thread for a single-threaded handle.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            None => f(),
            Some(p) => p.install(f),
        }
    }

    /// `f(i)` for every `i` in `0..n`, in parallel on the pool, results in order.
    pub fn map<R: Send>(&self, n: usize, f: impl Fn(usize) -> R + Sync + Send) -> Vec<R> {
        match &self.pool {
            None => (0..n).map(f).collect(),
            Some(p) => p.install(|| (0..n).into_par_iter().map(f).collect()),
        }
    }

    /// `f((i, item))` for every item of `items`, in parallel on the pool, results in order; one
    /// after the other on the calling thread for a single-threaded handle (a rayon parallel
    /// iterator run there would reach rayon's global pool, every core, behind the caller's back).
    pub fn map_vec<T: Send, R: Send>(&self, items: Vec<T>, f: impl Fn((usize, T)) -> R + Sync + Send) -> Vec<R> {
        match &self.pool {
            // One item has nothing to share: no hand-off to the pool.
            _ if items.len() < 2 => items.into_iter().enumerate().map(f).collect(),
            None => items.into_iter().enumerate().map(f).collect(),
            Some(p) => p.install(|| items.into_par_iter().enumerate().map(f).collect()),
        }
    }

    /// `(a(), b())`, the two at once on the pool, or one after the other on the calling thread
    /// for a single-threaded handle (as [`ThreadPool::map_vec`]).
    pub fn join<A: Send, B: Send>(&self, a: impl FnOnce() -> A + Send, b: impl FnOnce() -> B + Send) -> (A, B) {
        match &self.pool {
            None => (a(), b()),
            Some(p) => p.install(|| rayon::join(a, b)),
        }
    }

    /// `f(index, chunk)` for every `chunk_len`-sized chunk of `data` (the last may be shorter),
    /// in parallel on the pool.
    pub fn for_each_chunk_mut<T: Send>(
        &self,
        data: &mut [T],
        chunk_len: usize,
        f: impl Fn(usize, &mut [T]) + Sync + Send,
    ) {
        let chunk_len = chunk_len.max(1);
        match &self.pool {
            None => data.chunks_mut(chunk_len).enumerate().for_each(|(i, c)| f(i, c)),
            Some(p) => p.install(|| data.par_chunks_mut(chunk_len).enumerate().for_each(|(i, c)| f(i, c))),
        }
    }

    /// Like [`ThreadPool::for_each_chunk_mut`] for work that can fail: the first error (in chunk
    /// order) is returned.
    pub fn try_for_each_chunk_mut<T: Send>(
        &self,
        data: &mut [T],
        chunk_len: usize,
        f: impl Fn(usize, &mut [T]) -> Result<()> + Sync + Send,
    ) -> Result<()> {
        let chunk_len = chunk_len.max(1);
        match &self.pool {
            None => data.chunks_mut(chunk_len).enumerate().try_for_each(|(i, c)| f(i, c)),
            Some(p) => {
                let results: Vec<Result<()>> =
                    p.install(|| data.par_chunks_mut(chunk_len).enumerate().map(|(i, c)| f(i, c)).collect());
                results.into_iter().collect()
            }
        }
    }
}

/// The number of cores this process may use (1 if unknown).
pub fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_runs_on_the_calling_thread() {
        let p = ThreadPool::single();
        assert_eq!(p.threads(), 1);
        let me = std::thread::current().id();
        assert!(p.map(4, |_| std::thread::current().id()).iter().all(|&t| t == me));
        assert_eq!(ThreadPool::new(1).unwrap(), ThreadPool::single());
    }

    #[test]
    fn map_vec_and_join_keep_order_and_a_single_handle_on_the_calling_thread() {
        let me = std::thread::current().id();
        let single = ThreadPool::single();
        let items: Vec<u32> = (0..64).collect();
        let out = single.map_vec(items.clone(), |(i, x)| (i, x * 2, std::thread::current().id()));
        assert!(out.iter().enumerate().all(|(k, &(i, x, t))| i == k && x == 2 * k as u32 && t == me));
        let (a, b) = single.join(|| std::thread::current().id(), || std::thread::current().id());
        assert_eq!((a, b), (me, me));
        let pool = ThreadPool::new(2).unwrap();
        let out = pool.map_vec(items, |(i, x)| i as u32 + x);
        assert_eq!(out, (0..64).map(|k| 2 * k).collect::<Vec<u32>>());
        assert_eq!(pool.join(|| 1, || 2), (1, 2));
    }

    #[test]
    fn pool_results_keep_their_order_and_the_first_error() {
        let p = ThreadPool::new(3).unwrap();
        assert_eq!(p.threads(), 3);
        assert_eq!(p.map(100, |i| i * 2), (0..100).map(|i| i * 2).collect::<Vec<_>>());
        let mut v = vec![0u32; 10];
        p.for_each_chunk_mut(&mut v, 3, |i, c| c.iter_mut().for_each(|x| *x = i as u32));
        assert_eq!(v, [0, 0, 0, 1, 1, 1, 2, 2, 2, 3]);
        let r = p.try_for_each_chunk_mut(&mut v, 2, |i, _| {
            if i >= 2 {
                Err(Error::invalid(format!("chunk {i}")))
            } else {
                Ok(())
            }
        });
        assert_eq!(r.unwrap_err().to_string(), "invalid input: chunk 2");
        // A clone shares the pool; a second pool is a different one.
        assert_eq!(p.clone(), p);
        assert_ne!(ThreadPool::new(3).unwrap(), p);
    }
}
