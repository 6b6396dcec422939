//! Memory hints: the one place graftal talks to the operating system about
//! memory (it knows nothing else of the crate, and any module may use it).
//!
//! [`prefault_spare`] has the pages of a vector's spare capacity mapped by
//! a short-lived helper thread while the caller goes on filling it. Why:
//! the kernel's big operators (a 1000² grid, extruding a million faces)
//! write hundreds of megabytes of new records front to back, and the first
//! write to each 4 KiB page costs a fault in which the kernel allocates and
//! zeroes it — about 2 µs a page on the 2-core development VM, a third of
//! a million-face grid's time (issue 17). `MADV_POPULATE_WRITE` (Linux 5.14)
//! does that work for a range without touching its contents; done on the
//! other core, ahead of the writer, the faults leave the critical path.
//!
//! It is a hint: contents, results and their determinism do not depend on
//! whether or when it runs. Elsewhere (other systems, older kernels, a
//! thread that cannot be spawned) it does nothing.

/// Spare capacity below this many bytes is left to fault as it is written
/// (a thread costs tens of microseconds; 8 MiB of faults about 4 ms here).
const PREFAULT_FROM: usize = 8 << 20;

/// Maps, in the background, the pages of `v`'s spare capacity that the next
/// `additional` elements will occupy (no more: pages never written would
/// only add to the resident size).
pub fn prefault_spare<T>(v: &mut Vec<T>, additional: usize) {
    let mut batch = Prefault::default();
    batch.add(v, additional);
    batch.start();
}

/// Several vectors an operator is about to fill side by side (the kernel's
/// four arenas): one helper thread maps them all, a slice of each in turn,
/// so it stays ahead of the writer in every one without taking more than
/// the one spare core.
#[derive(Default)]
pub struct Prefault {
    ranges: Vec<(usize, usize)>,
}

impl Prefault {
    /// Adds the pages the next `additional` elements of `v` will occupy.
    pub fn add<T>(&mut self, v: &mut Vec<T>, additional: usize) {
        let spare = v.spare_capacity_mut();
        let count = additional.min(spare.len());
        let bytes = count.saturating_mul(std::mem::size_of::<T>());
        if bytes > 0 {
            self.ranges.push((spare.as_ptr() as usize, bytes));
        }
    }

    /// Starts the helper when the ranges are worth it.
    pub fn start(self) {
        let total: usize = self.ranges.iter().map(|&(_, bytes)| bytes).sum();
        if total >= PREFAULT_FROM {
            // Only address ranges cross to the thread: it never reads or
            // writes the memory, so the caller's writes cannot race with it.
            let _ = std::thread::Builder::new()
                .name("prefault".into())
                .spawn(move || populate(&self.ranges));
        }
    }
}

/// Maps the ranges' pages in steps, each step the next slice of every
/// range (slices proportional to the range, so all finish together): the
/// pages a writer filling the vectors side by side needs first are ready
/// first.
#[cfg(target_os = "linux")]
fn populate(ranges: &[(usize, usize)]) {
    const PAGE: usize = 4096;
    const SLICE: usize = 1 << 20;
    let pages = |(start, bytes): (usize, usize)| {
        let first = start.next_multiple_of(PAGE);
        (first, ((start + bytes) & !(PAGE - 1)).max(first))
    };
    let spans: Vec<(usize, usize)> = ranges.iter().map(|&r| pages(r)).collect();
    let steps = spans
        .iter()
        .map(|&(first, end)| (end - first).div_ceil(SLICE))
        .max()
        .unwrap_or(0);
    let mut live = vec![true; spans.len()];
    for step in 0..steps {
        for (k, &(first, end)) in spans.iter().enumerate() {
            let chunk = (end - first).div_ceil(steps).next_multiple_of(PAGE);
            let at = first + step * chunk;
            if !live[k] || at >= end {
                continue;
            }
            let len = chunk.min(end - at);
            // SAFETY: MADV_POPULATE_WRITE faults in the pages of the range
            // as a write would, without accessing their contents, so it
            // cannot race with the owner's writes. The range was spare
            // capacity of a live allocation when the hint was given; if the
            // allocation has since moved or been freed, the call fails
            // (unmapped: that range is dropped) or maps pages the allocator
            // holds anyway, changing no contents.
            let status =
                unsafe { libc::madvise(at as *mut libc::c_void, len, libc::MADV_POPULATE_WRITE) };
            if status != 0 {
                live[k] = false;
            }
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn populate(_ranges: &[(usize, usize)]) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefaulted_capacity_fills_as_usual() {
        // Large enough to take the helper thread; the vector is filled,
        // reallocated and dropped while it may still run.
        let n = 3 * PREFAULT_FROM / 8;
        let mut v: Vec<u64> = Vec::with_capacity(n);
        prefault_spare(&mut v, n);
        v.extend(0..n as u64);
        assert_eq!(v.iter().sum::<u64>(), (n as u64 - 1) * n as u64 / 2);
        v.reserve(n);
        prefault_spare(&mut v, n);
        assert_eq!(v[n - 1], n as u64 - 1);
        drop(v);
        // A small or empty request does nothing.
        let mut w: Vec<u8> = Vec::new();
        prefault_spare(&mut w, 100);
        assert!(w.is_empty());
        // Several vectors in one batch, of different sizes.
        let (mut a, mut b): (Vec<u32>, Vec<[f64; 3]>) =
            (Vec::with_capacity(n), Vec::with_capacity(n / 3));
        let mut batch = Prefault::default();
        batch.add(&mut a, n);
        batch.add(&mut b, n / 3);
        batch.start();
        a.extend(0..n as u32);
        b.extend((0..n / 3).map(|i| [i as f64; 3]));
        assert_eq!(
            (a[n - 1], b[n / 3 - 1][2]),
            (n as u32 - 1, (n / 3 - 1) as f64)
        );
    }
}
