//! Memory handed from one frame to the next, as a GPU pass keeps its
//! buffers: the bin writes its largest arrays whole every frame, and
//! fresh memory cost each frame its page faults, and a serial fill where
//! the array was initialised before being written (courtyard at 960×540:
//! the vertex cache's 59 MB 18 → 9 ms a frame; the cell lists' 12 MB,
//! see [`super::counting_sort`]).

use std::sync::Mutex;

/// One allocation kept for the next frame: the last one handed back (in
/// one stream of frames, the largest capacity so far: [`reused`] never
/// shrinks it), held until the process ends.
pub struct Spare<T>(Mutex<Option<T>>);

impl<T> Spare<T> {
    pub const fn new() -> Self {
        Spare(Mutex::new(None))
    }

    /// The kept allocation, if any (a frame running beside another may
    /// find none and allocate its own).
    pub fn take(&self) -> Option<T> {
        self.0.lock().ok().and_then(|mut kept| kept.take())
    }

    /// Keeps `value` for the next [`Self::take`].
    pub fn keep(&self, value: T) {
        if let Ok(mut kept) = self.0.lock() {
            *kept = Some(value);
        }
    }
}

/// `spare` at length `len` where it has the room, else a new vector (a
/// grown one would copy what it held first). What it held is left in it:
/// for arrays the caller writes whole.
pub fn reused<T: Copy>(mut spare: Vec<T>, len: usize, zero: T) -> Vec<T> {
    if spare.capacity() < len {
        return vec![zero; len];
    }
    spare.resize(len, zero);
    spare
}
