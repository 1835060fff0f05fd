//! Two-stage pipelines on two cores: the calling thread *produces* items in order into
//! batches, a second thread *consumes* the batches in the same order while the next one is
//! produced. For the serial tails of the builds (a k-way merge feeding a file encoder, a
//! unit's records feeding its run file), which otherwise leave a core idle.
//!
//! The order of consumption is the order of production, so what the consumer writes is what
//! the serial loop wrote, byte for byte. At most [`IN_FLIGHT`] full batches wait between the
//! stages, so the memory held is bounded by the batch size.
//!
//! Errors: a consumer's error stops the producer at its next [`Feed::push`] (which returns
//! [`Stopped`]) and is the one returned; otherwise the producer's error is returned. A panic
//! on either side propagates.

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

use crate::MethodError;

/// Full batches that may wait for the consumer.
pub const IN_FLIGHT: usize = 2;

/// The consumer has stopped (after an error): produce no more.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stopped;

impl From<Stopped> for MethodError {
    fn from(_: Stopped) -> Self {
        // Never returned to a caller: `overlapped` returns the consumer's own error instead.
        MethodError::Limit("the consuming stage of a pipeline stopped".into())
    }
}

/// The producer's end: items go into the current batch, full batches to the consumer.
pub struct Feed<T> {
    batch: Vec<T>,
    cap: usize,
    tx: SyncSender<Vec<T>>,
}

impl<T> Feed<T> {
    /// Hands `item` on (in order). `Err(Stopped)` once the consumer has stopped.
    pub fn push(&mut self, item: T) -> Result<(), Stopped> {
        self.batch.push(item);
        if self.batch.len() == self.cap {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), Stopped> {
        if self.batch.is_empty() {
            return Ok(());
        }
        let full = std::mem::replace(&mut self.batch, Vec::with_capacity(self.cap));
        self.tx.send(full).map_err(|_| Stopped)
    }
}

/// Runs `produce` on this thread and `consume` on a second one, over batches of `batch`
/// items (see the module docs); returns the consumer's `state` once every item has been
/// consumed.
pub fn overlapped<T, S, E>(
    state: S,
    batch: usize,
    consume: impl FnMut(&mut S, Vec<T>) -> Result<(), E> + Send,
    produce: impl FnOnce(&mut Feed<T>) -> Result<(), E>,
) -> Result<S, E>
where
    T: Send,
    S: Send,
    E: Send + From<Stopped>,
{
    overlapped_with(state, batch, IN_FLIGHT, consume, produce)
}

/// [`overlapped`] with at most `waiting` full batches between the stages instead of
/// [`IN_FLIGHT`]. With `waiting = 0` a batch is handed over only when the consumer takes it:
/// at most two batches exist at once (the one consumed and the one produced, which waits in
/// [`Feed::push`]), for stages whose batches are large (a whole unit of a build).
pub fn overlapped_with<T, S, E>(
    state: S,
    batch: usize,
    waiting: usize,
    mut consume: impl FnMut(&mut S, Vec<T>) -> Result<(), E> + Send,
    produce: impl FnOnce(&mut Feed<T>) -> Result<(), E>,
) -> Result<S, E>
where
    T: Send,
    S: Send,
    E: Send + From<Stopped>,
{
    let batch = batch.max(1);
    let (tx, rx): (SyncSender<Vec<T>>, Receiver<Vec<T>>) = sync_channel(waiting);
    std::thread::scope(|scope| {
        let consumer = scope.spawn(move || -> Result<S, E> {
            let mut state = state;
            for items in rx {
                // Returning drops `rx`: the producer's next send fails.
                consume(&mut state, items)?;
            }
            Ok(state)
        });
        let mut feed = Feed {
            batch: Vec::with_capacity(batch),
            cap: batch,
            tx,
        };
        let produced = produce(&mut feed).and_then(|()| feed.flush().map_err(E::from));
        // Closing the channel ends the consumer's loop.
        drop(feed);
        let consumed = match consumer.join() {
            Ok(c) => c,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        let state = consumed?;
        produced?;
        Ok(state)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn consumes_every_item_in_order_across_batch_boundaries() {
        for (n, batch) in [(0usize, 4usize), (1, 4), (4, 4), (5, 4), (1000, 7), (10, 0)] {
            let seen = overlapped(
                Vec::new(),
                batch,
                |s: &mut Vec<usize>, items| {
                    s.extend(items);
                    Ok::<(), MethodError>(())
                },
                |feed| {
                    for i in 0..n {
                        feed.push(i)?;
                    }
                    Ok(())
                },
            )
            .unwrap();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "n {n} batch {batch}");
        }
    }

    #[test]
    fn a_consumer_error_stops_the_producer_and_is_the_one_returned() {
        let mut produced = 0usize;
        let err = overlapped(
            0usize,
            10,
            |s: &mut usize, items: Vec<usize>| {
                *s += items.len();
                if *s >= 30 {
                    return Err(MethodError::Limit("disk full".into()));
                }
                Ok(())
            },
            |feed| {
                for i in 0..1_000_000 {
                    feed.push(i)?;
                    produced += 1;
                }
                Ok(())
            },
        )
        .unwrap_err();
        assert_eq!(err.to_string(), "disk full");
        // The producer stopped: at most the failing batch, the batches in flight and the one
        // being filled were produced past the 30 consumed.
        assert!(produced <= 30 + 10 * (IN_FLIGHT + 2), "produced {produced}");
    }

    #[test]
    fn with_nothing_waiting_at_most_two_batches_exist_at_once() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        // Batches alive: counted up when one is produced, down when the consumer drops it.
        let alive = AtomicUsize::new(0);
        let most = AtomicUsize::new(0);
        let seen = overlapped_with(
            Vec::new(),
            1,
            0,
            |s: &mut Vec<usize>, items: Vec<usize>| {
                std::thread::sleep(std::time::Duration::from_millis(2));
                s.extend(items);
                alive.fetch_sub(1, Ordering::SeqCst);
                Ok::<(), MethodError>(())
            },
            |feed| {
                for i in 0..20 {
                    let now = alive.fetch_add(1, Ordering::SeqCst) + 1;
                    most.fetch_max(now, Ordering::SeqCst);
                    feed.push(i)?;
                }
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(seen, (0..20).collect::<Vec<_>>());
        assert_eq!(alive.load(Ordering::SeqCst), 0);
        // One being consumed, one produced and waiting to be taken; never a third.
        assert_eq!(most.load(Ordering::SeqCst), 2);
    }

    #[test]
    fn a_producer_error_is_returned_after_the_consumer_drains() {
        let mut consumed = 0usize;
        let err = overlapped(
            (),
            4,
            |_, items: Vec<usize>| {
                consumed += items.len();
                Ok(())
            },
            |feed| {
                for i in 0..9 {
                    feed.push(i)?;
                }
                Err(MethodError::Limit("bad input at 9".into()))
            },
        )
        .unwrap_err();
        assert_eq!(err.to_string(), "bad input at 9");
        // The two full batches were consumed; the partial one was not flushed.
        assert_eq!(consumed, 8);
    }
}
