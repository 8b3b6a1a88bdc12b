//! Per-item marks that are all forgotten at once, in constant time: the
//! scratch of queries that run once per pixel and must not clear a buffer
//! the size of the level's edges each time.

/// A value per item (`0..len`) that holds only until the next
/// [`Marks::clear`]. Each slot keeps the generation it was set in; clearing
/// starts a new generation, so older slots read as unset. When the counter
/// wraps round, the slots are reset for real.
#[derive(Clone, Debug, Default)]
pub struct Marks<T> {
    generation: u32,
    slots: Vec<(u32, T)>,
}

impl<T: Copy + Default> Marks<T> {
    /// Forgets every mark, for `len` items from now on.
    #[inline]
    pub fn clear(&mut self, len: usize) {
        if self.slots.len() != len {
            self.slots = vec![(0, T::default()); len];
            self.generation = 0;
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.slots.fill((0, T::default()));
            self.generation = 1;
        }
    }

    /// Number of items.
    #[inline]
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    #[inline]
    /// No items.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Item `i`'s value, if it was set since the last clear (`None` also
    /// for `i` out of range).
    #[inline]
    pub fn get(&self, i: usize) -> Option<T> {
        match self.slots.get(i) {
            Some(&(g, v)) if g == self.generation => Some(v),
            _ => None,
        }
    }

    #[inline]
    /// Sets item `i`'s value until the next clear.
    pub fn set(&mut self, i: usize, v: T) {
        self.slots[i] = (self.generation, v);
    }

    /// Unsets item `i` (stamped one generation back: the counter only
    /// reaches that value again after a wrap, which resets every slot).
    #[inline]
    pub fn unset(&mut self, i: usize) {
        self.slots[i].0 = self.generation.wrapping_sub(1);
    }

    /// Sets item `i` to the default value; false if it was already set.
    #[inline]
    pub fn insert(&mut self, i: usize) -> bool {
        let fresh = self.slots[i].0 != self.generation;
        self.slots[i] = (self.generation, T::default());
        fresh
    }
}

#[cfg(test)]
mod tests {
    use super::Marks;

    #[test]
    fn clear_forgets_and_wrap_round_resets() {
        let mut m: Marks<u32> = Marks::default();
        m.clear(3);
        assert_eq!(m.get(1), None);
        m.set(1, 7);
        assert_eq!(m.get(1), Some(7));
        assert!(m.insert(2));
        assert!(!m.insert(2));
        m.unset(1);
        assert_eq!(m.get(1), None);
        m.set(0, 5);
        m.clear(3);
        assert_eq!((m.get(0), m.get(2)), (None, None));
        // Force the counter round: a slot set long ago must not come back.
        m.set(0, 9);
        m.generation = u32::MAX;
        m.slots[1] = (1, 4);
        m.clear(3);
        assert_eq!(m.generation, 1);
        assert_eq!((m.get(0), m.get(1), m.get(2)), (None, None, None));
        // Another length reallocates.
        m.set(2, 1);
        m.clear(5);
        assert_eq!((m.len(), m.get(2), m.get(4)), (5, None, None));
        assert_eq!(m.get(9), None);
    }
}
