//! Uploads of arrays that grow with the mesh (per-tet and per-vertex arrays, active lists), in
//! pieces of bounded size written straight into wgpu's staging memory ([`Uploader`]).
//!
//! One `Queue::write_buffer` of a whole array makes wgpu allocate one staging buffer of its
//! size and keep it until the next submission completes, so the host holds the source, the
//! staging copy and (on a software adapter) the buffer itself at once: 3.2 GB of ray-caster
//! links for a 100M-tet grid becomes 6.4 GB or more of host memory. Here each piece of at most
//! [`PIECE`] bytes is filled in parallel in its own staging buffer, either from a slice or from
//! a closure that computes entry `i` (so no whole intermediate array is built), then submitted;
//! at most [`IN_FLIGHT`] pieces wait for their copy, so the staging memory stays under
//! `(IN_FLIGHT + 1) * PIECE` whatever the array. A write of one piece is submitted too: left
//! for the next frame's submission, as `write_buffer` leaves it, every write until then keeps
//! its staging copy (200 position updates of a 41k-vertex mesh between two frames held 110 MB
//! on lavapipe). Submitting only moves the copy earlier in the queue, which runs writes before
//! any command buffer submitted after them either way, and costs about 25 us a write (4 KiB
//! writes on lavapipe: 33-36 us each against 7-11 us for `write_buffer`), a few per frame.

use std::collections::VecDeque;

use rayon::prelude::*;

/// Most bytes of one piece: 16 MiB, the fastest measured. Writing 480 MiB of 32-byte entries
/// (a 15M-tet grid's links) on lavapipe (2 cores, other builds running; 3 rounds): pieces of
/// 64, 32, 16, 8, 4 and 1 MiB took 82-272, 63-74, 43-45, 51-63, 56-66 and 72-85 ms, one
/// `write_buffer` of the whole array 260-280 ms. Pieces of a few MiB reuse the staging memory
/// the allocator freed (a whole-array staging buffer is fresh memory, faulted in page by page)
/// and stay in cache until copied; below that the per-piece submission and wait dominate. The
/// staging memory in use then stays under (IN_FLIGHT + 1) x 16 MiB = 48 MiB, and the 3.2 GB
/// of a 100M-tet grid's links are 200 submissions.
pub(crate) const PIECE: u64 = 16 << 20;

/// Pieces submitted but not yet waited for: the copy of one overlaps the fill of the next.
const IN_FLIGHT: usize = 2;

/// Bytes filled per task within a piece (whole entries of every size written, see
/// [`entry_size`]): small enough that a task's entries stay in the core's cache before their
/// copy into staging memory.
const TASK: usize = 1 << 18;

/// Where uploads go: the device (to wait for pieces) and its queue, and the piece size.
#[derive(Clone, Copy)]
pub(crate) struct Uploader<'a> {
    pub device: &'a wgpu::Device,
    pub queue: &'a wgpu::Queue,
    /// Most bytes per piece ([`PIECE`]; tests take small ones to cross many pieces).
    pub piece: u64,
}

impl<'a> Uploader<'a> {
    /// Uploads through `queue` in pieces of [`PIECE`].
    pub(crate) fn new(device: &'a wgpu::Device, queue: &'a wgpu::Queue) -> Self {
        Self {
            device,
            queue,
            piece: PIECE,
        }
    }

    /// Writes `count` entries to `buffer` from byte `offset` on, entry `i` being `entry(i)`,
    /// computed in parallel straight into the staging memory of each piece (no whole
    /// intermediate array). A write wgpu refuses is reported by wgpu's error handler, as
    /// `Queue::write_buffer`'s would be.
    pub(crate) fn entries<T: bytemuck::Pod + Send>(
        self,
        buffer: &wgpu::Buffer,
        offset: u64,
        count: usize,
        entry: impl Fn(usize) -> T + Sync,
    ) {
        let stride = const { entry_size::<T>() };
        self.write(buffer, offset, count * stride, stride, |mut part, first| {
            let from = first / stride;
            let values: Vec<T> = (from..from + part.len() / stride).map(&entry).collect();
            part.copy_from_slice(bytemuck::cast_slice(&values));
        });
    }

    /// Writes `data` to `buffer` from byte `offset` on (a whole number of 4-byte words, as
    /// `Queue::write_buffer` needs).
    pub(crate) fn slice<T: bytemuck::Pod>(self, buffer: &wgpu::Buffer, offset: u64, data: &[T]) {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let word = wgpu::COPY_BUFFER_ALIGNMENT as usize;
        self.write(buffer, offset, bytes.len(), word, |mut part, first| {
            part.copy_from_slice(&bytes[first..first + part.len()]);
        });
    }

    /// Writes `len` bytes from `offset` on in pieces of whole `stride`-byte entries, each
    /// piece's staging memory filled by `fill` in parallel tasks of [`TASK`] bytes (and the
    /// rest; `fill` gets the task's memory and its first byte of the `len`); submits each piece
    /// (so that the submission's completion frees its staging memory) and bounds the pieces in
    /// flight. The last piece goes first: a write wgpu refuses (past the buffer's end, a size
    /// that is no whole word) is then refused before any piece is written, as `write_buffer`
    /// refuses it whole.
    fn write(
        self,
        buffer: &wgpu::Buffer,
        offset: u64,
        len: usize,
        stride: usize,
        fill: impl Fn(wgpu::WriteOnly<'_, [u8]>, usize) + Sync,
    ) {
        let piece = (self.piece as usize / stride).max(1) * stride;
        let mut in_flight = VecDeque::new();
        for first in (0..len).step_by(piece).rev() {
            let Some(size) = wgpu::BufferSize::new(piece.min(len - first) as u64) else {
                return;
            };
            let at = offset + first as u64;
            let Some(mut view) = self.queue.write_buffer_with(buffer, at, size) else {
                return;
            };
            let (tasks, tail) = view.slice(..).into_chunks::<TASK>();
            let whole = first + tasks.len() * TASK;
            let tasks: Vec<_> = tasks.into_iter().enumerate().collect();
            (tasks.into_par_iter()).for_each(|(t, task)| fill(task.into(), first + t * TASK));
            fill(tail, whole);
            drop(view);
            in_flight.push_back(self.queue.submit([]));
            if in_flight.len() > IN_FLIGHT {
                self.wait(in_flight.pop_front());
            }
        }
    }

    /// Waits until `submission` completed, which frees its pieces' staging memory. A device
    /// lost while waiting is reported by the next call that needs the device.
    fn wait(self, submission: Option<wgpu::SubmissionIndex>) {
        let _ = self.device.poll(wgpu::PollType::Wait {
            submission_index: submission,
            timeout: None,
        });
    }
}

/// The size of an entry written: a multiple of 4 bytes, as buffer copies need
/// (`wgpu::COPY_BUFFER_ALIGNMENT`), and a divisor of a task, so tasks hold whole entries.
const fn entry_size<T>() -> usize {
    let size = size_of::<T>();
    assert!(size > 0 && size.is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT as usize));
    assert!(TASK.is_multiple_of(size));
    size
}
