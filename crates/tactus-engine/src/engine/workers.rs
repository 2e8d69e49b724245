//! Offline stem chains on threads of their own, fed separated blocks through bounded queues.
//!
//! # Why
//! The pipelined engine ran every chain of a block on its own scoped thread and joined them
//! before the next block: each block waited for its slowest chain (the lead's, a third of
//! the render's work) while the other core sat idle, since the operating system shares the
//! cores fairly among the threads that are left. Here each chain keeps one thread for the
//! whole song and takes the next block as soon as it is done with the last, so a core idles
//! only when every chain has caught up with the separator.
//!
//! # Exactness
//! Every chain sees the same blocks in the same order as on the calling thread (the same
//! [`super::chain::feed`] on one chain), so every output is the same, bit for bit.
//!
//! # Memory
//! A queue holds at most [`QUEUE`] blocks per chain; the separator waits when a chain is
//! that far behind.

use std::sync::mpsc::{sync_channel, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;

use tactus_dsp::Stem;
use tactus_separate::StemOutput;

use super::chain::{feed, StemChain};

/// Blocks a chain's queue may hold.
const QUEUE: usize = 2;

/// A separated block and the same span of every supplied stem.
pub(super) struct Block {
    pub(super) out: StemOutput,
    pub(super) supplied: Vec<(Stem, Vec<f32>)>,
}

/// One thread per chain, each owning its chain until [`Workers::join`].
pub(super) struct Workers {
    senders: Vec<SyncSender<Arc<Block>>>,
    handles: Vec<JoinHandle<StemChain>>,
}

impl Workers {
    /// Moves each chain onto a thread of its own.
    pub(super) fn start(chains: Vec<StemChain>) -> Workers {
        let (mut senders, mut handles) = (Vec::new(), Vec::new());
        for mut chain in chains {
            let (tx, rx) = sync_channel::<Arc<Block>>(QUEUE);
            senders.push(tx);
            handles.push(std::thread::spawn(move || {
                for block in rx {
                    let views: Vec<(Stem, &[f32])> = block
                        .supplied
                        .iter()
                        .map(|(s, x)| (*s, x.as_slice()))
                        .collect();
                    feed(std::slice::from_mut(&mut chain), &block.out, &views, false);
                }
                chain
            }));
        }
        Workers { senders, handles }
    }

    /// Hands a block to every chain; waits while a chain's queue is full.
    pub(super) fn send(&self, block: Block) {
        let block = Arc::new(block);
        for tx in &self.senders {
            // A chain's thread ends only when its queue is closed or it panicked; a panic
            // comes back from `join`.
            let _ = tx.send(Arc::clone(&block));
        }
    }

    /// Waits for every chain to finish its queue and returns the chains in their order; a
    /// chain's panic is resumed here, as a scoped thread's would be.
    pub(super) fn join(self) -> Vec<StemChain> {
        drop(self.senders);
        self.handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    }
}
