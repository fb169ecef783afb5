//! Undo/redo of the document's editable state by snapshots: one checkpoint per user action
//! (a landmark placement, a slider drag from press to release), never one per frame.

/// Snapshot history of a `Clone` state.
#[derive(Debug, Clone)]
pub struct History<T> {
    undo: Vec<T>,
    redo: Vec<T>,
    /// Oldest snapshots are dropped past this many (memory stays bounded in long sessions).
    limit: usize,
}

impl<T: Clone + PartialEq> History<T> {
    pub fn new(limit: usize) -> Self {
        History {
            undo: Vec::new(),
            redo: Vec::new(),
            limit: limit.max(1),
        }
    }

    /// Records `before` (the state just before an edit); clears the redo branch. A snapshot
    /// equal to the last one is not stored twice.
    pub fn checkpoint(&mut self, before: &T) {
        if self.undo.last() != Some(before) {
            self.undo.push(before.clone());
            if self.undo.len() > self.limit {
                self.undo.remove(0);
            }
        }
        self.redo.clear();
    }

    /// Steps back: returns the state to restore, keeping `current` for redo.
    pub fn undo(&mut self, current: &T) -> Option<T> {
        let previous = self.undo.pop()?;
        self.redo.push(current.clone());
        Some(previous)
    }

    /// Steps forward again after an undo.
    pub fn redo(&mut self, current: &T) -> Option<T> {
        let next = self.redo.pop()?;
        self.undo.push(current.clone());
        Some(next)
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    pub fn clear(&mut self) {
        self.undo.clear();
        self.redo.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undo_redo_walks_the_edits_and_a_new_edit_drops_the_redo_branch() {
        let mut h = History::new(10);
        let mut state = 0;
        for next in [1, 2, 3] {
            h.checkpoint(&state);
            state = next;
        }
        state = h.undo(&state).unwrap();
        assert_eq!(state, 2);
        state = h.undo(&state).unwrap();
        assert_eq!(state, 1);
        state = h.redo(&state).unwrap();
        assert_eq!(state, 2);
        h.checkpoint(&state);
        state = 7;
        assert!(!h.can_redo());
        assert_eq!(h.undo(&state), Some(2));
    }

    #[test]
    fn history_is_bounded_and_does_not_repeat_equal_snapshots() {
        let mut h = History::new(3);
        for s in 0..10 {
            h.checkpoint(&s);
            h.checkpoint(&s);
        }
        let mut state = 10;
        let mut seen = Vec::new();
        while let Some(s) = h.undo(&state) {
            seen.push(s);
            state = s;
        }
        assert_eq!(seen, vec![9, 8, 7]);
    }
}
