//! Bounded hand-over between two pipeline threads, with the two policies the pipeline needs:
//! a real-time stage keeps the newest items and counts what it drops ([`StageQueue::push_newest`]),
//! a lossless one makes the producer wait ([`StageQueue::push_wait`]). The producer closes the
//! queue when it ends; the consumer then drains what is left and sees `None`.
//!
//! Also [`LatestSlot`]: a one-item "newest wins" slot for displays, counting the results that were
//! replaced before anyone took them.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

struct State<T> {
    items: VecDeque<T>,
    closed: bool,
    dropped: u64,
}

pub struct StageQueue<T> {
    capacity: usize,
    state: Mutex<State<T>>,
    changed: Condvar,
}

/// A poisoned lock only means another pipeline thread panicked; the data (a queue of frames,
/// counters) is still consistent, so carry on with it.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl<T> StageQueue<T> {
    pub fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            state: Mutex::new(State {
                items: VecDeque::with_capacity(capacity.max(1)),
                closed: false,
                dropped: 0,
            }),
            changed: Condvar::new(),
        }
    }

    /// Adds `item`; when full, the oldest waiting item is dropped (and counted). Returns whether
    /// one was dropped.
    pub fn push_newest(&self, item: T) -> bool {
        let mut s = lock(&self.state);
        let dropped = s.items.len() >= self.capacity;
        if dropped {
            s.items.pop_front();
            s.dropped += 1;
        }
        s.items.push_back(item);
        drop(s);
        self.changed.notify_all();
        dropped
    }

    /// Adds `item`, waiting while the queue is full. Returns `false` if the queue was closed.
    pub fn push_wait(&self, item: T) -> bool {
        let mut s = lock(&self.state);
        while s.items.len() >= self.capacity && !s.closed {
            s = self.changed.wait(s).unwrap_or_else(PoisonError::into_inner);
        }
        if s.closed {
            return false;
        }
        s.items.push_back(item);
        drop(s);
        self.changed.notify_all();
        true
    }

    /// Waits until the queue has room for one more item. Returns `false` if it was closed. A
    /// lossless producer calls this before it produces (reads, renders) its next item, so that
    /// the item does not sit finished in the producer while the queue is full: that wait would
    /// add to its latency and gain nothing. With one producer the room stays until it pushes.
    pub fn wait_for_room(&self) -> bool {
        let mut s = lock(&self.state);
        while s.items.len() >= self.capacity && !s.closed {
            s = self.changed.wait(s).unwrap_or_else(PoisonError::into_inner);
        }
        !s.closed
    }

    /// Takes the oldest item, waiting for one; `None` once closed and empty.
    pub fn pop(&self) -> Option<T> {
        let mut s = lock(&self.state);
        loop {
            if let Some(item) = s.items.pop_front() {
                drop(s);
                self.changed.notify_all();
                return Some(item);
            }
            if s.closed {
                return None;
            }
            s = self.changed.wait(s).unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// Takes the oldest item if there is one, without waiting.
    pub fn try_pop(&self) -> Option<T> {
        let item = lock(&self.state).items.pop_front();
        if item.is_some() {
            self.changed.notify_all();
        }
        item
    }

    /// Whether the producer has closed the queue and every item has been taken.
    pub fn is_finished(&self) -> bool {
        let s = lock(&self.state);
        s.closed && s.items.is_empty()
    }

    pub fn close(&self) {
        lock(&self.state).closed = true;
        self.changed.notify_all();
    }

    /// Items dropped by [`Self::push_newest`] so far.
    pub fn dropped(&self) -> u64 {
        lock(&self.state).dropped
    }
}

/// The newest result for a display.
pub struct LatestSlot<T> {
    state: Mutex<(Option<T>, u64)>,
}

impl<T> Default for LatestSlot<T> {
    fn default() -> Self {
        Self {
            state: Mutex::new((None, 0)),
        }
    }
}

impl<T> LatestSlot<T> {
    /// Puts `item`, replacing (and counting) one nobody took.
    pub fn put(&self, item: T) {
        let mut s = lock(&self.state);
        if s.0.replace(item).is_some() {
            s.1 += 1;
        }
    }

    /// Takes the newest item, if there is one not yet taken.
    pub fn take(&self) -> Option<T> {
        lock(&self.state).0.take()
    }

    /// Results replaced before they were taken.
    pub fn overwritten(&self) -> u64 {
        lock(&self.state).1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn newest_policy_drops_the_oldest_and_counts() {
        let q = StageQueue::new(2);
        assert!(!q.push_newest(1));
        assert!(!q.push_newest(2));
        assert!(q.push_newest(3));
        q.close();
        assert_eq!(q.pop(), Some(2));
        assert_eq!(q.pop(), Some(3));
        assert_eq!(q.pop(), None);
        assert_eq!(q.dropped(), 1);
    }

    #[test]
    fn wait_policy_loses_nothing() {
        let q = Arc::new(StageQueue::new(1));
        let producer = {
            let q = Arc::clone(&q);
            std::thread::spawn(move || {
                for i in 0..100 {
                    assert!(q.push_wait(i));
                }
                q.close();
            })
        };
        let got: Vec<i32> = std::iter::from_fn(|| q.pop()).collect();
        producer.join().unwrap();
        assert_eq!(got, (0..100).collect::<Vec<_>>());
        assert_eq!(q.dropped(), 0);
    }

    #[test]
    fn waiting_for_room_returns_once_an_item_is_taken_or_the_queue_closes() {
        let q = Arc::new(StageQueue::new(1));
        assert!(q.wait_for_room(), "an empty queue has room");
        assert!(q.push_wait(1));
        let waiter = {
            let q = Arc::clone(&q);
            std::thread::spawn(move || q.wait_for_room())
        };
        std::thread::sleep(std::time::Duration::from_millis(50));
        assert!(!waiter.is_finished(), "a full queue has no room");
        assert_eq!(q.pop(), Some(1));
        assert!(waiter.join().unwrap(), "the pop made room");
        assert!(q.push_wait(2));
        let waiter = {
            let q = Arc::clone(&q);
            std::thread::spawn(move || q.wait_for_room())
        };
        std::thread::sleep(std::time::Duration::from_millis(50));
        assert!(!waiter.is_finished());
        q.close();
        assert!(!waiter.join().unwrap(), "closed: no room to wait for");
    }

    #[test]
    fn latest_slot_counts_unseen_results() {
        let slot = LatestSlot::default();
        slot.put(1);
        slot.put(2);
        assert_eq!(slot.take(), Some(2));
        assert_eq!(slot.take(), None);
        slot.put(3);
        assert_eq!(slot.overwritten(), 1);
    }
}
