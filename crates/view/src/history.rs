//! Undo and redo of the panel's scene edits.
//!
//! The viewer observes what the panel edits once a frame (a snapshot: the
//! materials' tables, the point lights, the environment; not the camera,
//! which "Reset to the scene's camera" restores). Frames in which the
//! snapshot keeps changing form one *burst* (a drag of a value, a colour
//! picked, a light moved), and a burst is one undo step: `Ctrl+Z` goes
//! back to the state before it, `Ctrl+Shift+Z` or `Ctrl+Y` forward
//! again. A burst ends with the first frame that changes nothing while
//! no mouse button is held ([`History::observe_held`]: a slow drag, on a
//! CPU driver's frames of half a second, has frames between its moves
//! that change nothing), and a drag's release draws one. A new edit after
//! an undo drops the steps that could have been redone. At most
//! [`History::LIMIT`] steps are kept.

/// Undo and redo stacks over snapshots of type `T`.
#[derive(Clone, Debug)]
pub struct History<T> {
    undo: Vec<T>,
    redo: Vec<T>,
    /// The snapshot of the last frame observed.
    last: T,
    /// Whether the last frame observed changed the snapshot.
    burst: bool,
}

impl<T: Clone + PartialEq> History<T> {
    /// Steps kept.
    pub const LIMIT: usize = 100;

    /// A history starting at `start`, with nothing to undo.
    pub fn new(start: T) -> Self {
        Self {
            undo: Vec::new(),
            redo: Vec::new(),
            last: start,
            burst: false,
        }
    }

    /// Observes a frame's snapshot: the start of a burst of changes saves
    /// the state before it as an undo step; a frame that changes nothing
    /// ends the burst.
    pub fn observe(&mut self, now: &T) {
        self.observe_held(now, false);
    }

    /// [`History::observe`] for a frame drawn while a mouse button is
    /// `held` or not: while held, a frame that changes nothing does not
    /// end the burst, so that a whole drag is one step however slowly the
    /// frames come.
    pub fn observe_held(&mut self, now: &T, held: bool) {
        if *now == self.last {
            self.burst &= held;
            return;
        }
        if !self.burst {
            let before = std::mem::replace(&mut self.last, now.clone());
            self.undo.push(before);
            if self.undo.len() > Self::LIMIT {
                self.undo.remove(0);
            }
            self.redo.clear();
            self.burst = true;
        } else {
            self.last = now.clone();
        }
    }

    /// The state to go back to from `now`, if any (`now` becomes a redo
    /// step).
    pub fn undo(&mut self, now: &T) -> Option<T> {
        self.step(now, true)
    }

    /// The state to go forward to from `now`, if any.
    pub fn redo(&mut self, now: &T) -> Option<T> {
        self.step(now, false)
    }

    fn step(&mut self, now: &T, back: bool) -> Option<T> {
        let (from, to) = if back {
            (&mut self.undo, &mut self.redo)
        } else {
            (&mut self.redo, &mut self.undo)
        };
        let target = from.pop()?;
        to.push(now.clone());
        self.last = target.clone();
        self.burst = false;
        Some(target)
    }

    /// Steps that can be undone and redone.
    pub fn depth(&self) -> (usize, usize) {
        (self.undo.len(), self.redo.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames that keep changing are one step; a still frame ends it.
    #[test]
    fn a_burst_of_changes_is_one_step() {
        let mut h = History::new(0);
        for v in [1, 2, 3, 3, 3, 7, 8, 8] {
            h.observe(&v);
        }
        assert_eq!(h.depth(), (2, 0));
        assert_eq!(h.undo(&8), Some(3));
        // The restored state observed is not a new edit.
        h.observe(&3);
        assert_eq!(h.depth(), (1, 1));
        assert_eq!(h.undo(&3), Some(0));
        assert_eq!(h.undo(&0), None);
        assert_eq!(h.redo(&0), Some(3));
        assert_eq!(h.redo(&3), Some(8));
        assert_eq!(h.redo(&8), None);
        assert_eq!(h.depth(), (2, 0));
    }

    /// While a button is held, still frames between changes do not end
    /// the burst; the first still frame after the release does.
    #[test]
    fn a_slow_drag_is_one_step() {
        let mut h = History::new(0);
        for (v, held) in [
            (1, true),
            (1, true),
            (2, true),
            (2, true),
            (3, true),
            (3, false),
        ] {
            h.observe_held(&v, held);
        }
        assert_eq!(h.depth(), (1, 0));
        h.observe_held(&4, true);
        assert_eq!(h.depth(), (2, 0));
        assert_eq!(h.undo(&4), Some(3));
        assert_eq!(h.undo(&3), Some(0));
    }

    /// An edit after an undo drops the redo steps, and an edit right
    /// after an undo or redo starts a step of its own.
    #[test]
    fn a_new_edit_drops_the_redo_steps() {
        let mut h = History::new(0);
        h.observe(&1);
        h.observe(&1);
        h.observe(&2);
        h.observe(&2);
        assert_eq!(h.undo(&2), Some(1));
        h.observe(&5);
        assert_eq!(h.depth(), (2, 0));
        assert_eq!(h.undo(&5), Some(1));
        assert_eq!(h.undo(&1), Some(0));
    }

    #[test]
    fn at_most_limit_steps_are_kept() {
        let mut h = History::new(0usize);
        for v in 1..=History::<usize>::LIMIT + 20 {
            h.observe(&v);
            h.observe(&v);
        }
        assert_eq!(h.depth().0, History::<usize>::LIMIT);
        let mut now = History::<usize>::LIMIT + 20;
        while let Some(s) = h.undo(&now) {
            now = s;
        }
        assert_eq!(now, 20, "the oldest steps went first");
    }
}
