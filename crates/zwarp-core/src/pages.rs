//! Large per-frame buffers with transparent huge pages (a cost of Sec. 3.3's preparation, of
//! every warp's output and of every render target, not an algorithm of the paper).
//!
//! A 1080p layer allocates ~45 MB per preparation (samples and level-1 mipmaps) and ~10 MB per
//! warp (depth and state). Freshly mapped memory is faulted in page by page on first write:
//! ~11 000 faults of 4 KiB per layer, which profiled at a quarter of all CPU time of the
//! `scenes` tool at L = 4 (the preparation at L >= 3 is a quarter of prepare + warp). Linux
//! keeps transparent huge pages for regions advised with `madvise(MADV_HUGEPAGE)` (the common
//! `enabled = madvise` setting), which turns those into a few dozen 2 MiB faults. The advice is
//! given before the buffer is first written; it is only a hint (ignored elsewhere or on error).

use rayon::prelude::*;

/// Buffers smaller than this are not advised (a huge page needs 2 MiB of aligned span).
const MIN_BYTES: usize = 4 << 20;

/// A `Vec` of `n` copies of `value`, its memory advised for huge pages before it is written
/// (written in parallel chunks).
pub fn filled<T: Copy + Send + Sync>(n: usize, value: T) -> Vec<T> {
    let mut v = uninit::<T>(n);
    v.spare_capacity_mut()[..n].par_chunks_mut(1 << 16).for_each(|c| {
        for e in c {
            e.write(value);
        }
    });
    // SAFETY: the loop above initialised all `n` elements of the spare capacity.
    unsafe { v.set_len(n) };
    v
}

/// `v` resized to `n` elements, reusing its allocation when it is large enough (a per-frame
/// buffer of the last frame); a new one is [`filled`]. The caller overwrites every element.
pub fn reuse<T: Copy + Send + Sync>(mut v: Vec<T>, n: usize, fill: T) -> Vec<T> {
    if v.capacity() >= n {
        v.resize(n, fill);
        v
    } else {
        filled(n, fill)
    }
}

/// An empty `Vec` with capacity for `n` elements, advised for huge pages; the caller writes the
/// first `n` elements through `spare_capacity_mut` and then sets the length.
pub fn uninit<T>(n: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(n);
    advise(v.as_ptr() as *const u8, n * std::mem::size_of::<T>());
    v
}

#[cfg(target_os = "linux")]
fn advise(ptr: *const u8, bytes: usize) {
    if bytes < MIN_BYTES {
        return;
    }
    // The advice applies to whole pages: round the start up and the end down to 4 KiB.
    const PAGE: usize = 4096;
    let start = (ptr as usize).div_ceil(PAGE) * PAGE;
    let end = (ptr as usize + bytes) / PAGE * PAGE;
    if end > start {
        // SAFETY: [start, end) lies inside the allocation just made (page-rounded inwards);
        // MADV_HUGEPAGE only changes how the kernel backs those pages, never their contents
        // or validity, and failure is harmless (the return value is ignored on purpose).
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_ptr: *const u8, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filled_buffers_hold_the_value_at_every_size() {
        for n in [0usize, 1, 7, 65_537, 3 << 20] {
            let v = filled(n, 1.5f32);
            assert_eq!(v.len(), n);
            assert!(v.iter().all(|&x| x == 1.5));
        }
        let v: Vec<u64> = uninit(10);
        assert_eq!((v.len(), v.capacity() >= 10), (0, true));
    }
}
