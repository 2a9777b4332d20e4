//! Storage for the packed scene's large arrays (primitives, grid cells,
//! references): in transparent huge pages where the OS offers them.
//!
//! The CPU tracer reads these arrays at random. With 1 M spheres they hold
//! about 100 MB, so on 4 KiB pages nearly every primitive test also misses
//! the TLB; in 2 MiB pages the whole scene fits the TLB's reach. Linux's
//! default THP mode ("madvise") gives huge pages only to memory that asks
//! for them, which a `Vec` cannot do without `unsafe`, so an array of
//! [`HUGE_MIN_BYTES`] or more is copied into an anonymous mapping that is
//! advised `MADV_HUGEPAGE` (memmap2's safe API). Smaller arrays stay in a
//! `Vec`. Measured in BENCHMARKS.md ("From 1 k to 1 M primitives"). The
//! `whitted` binary's allocator (jemalloc, `thp:always`) advises its own
//! mappings the same way (docs/architecture.md, "Memory") and says so
//! ([`allocator_gives_huge_pages`]): its arrays then stay where they are.
//! The copy keeps the render's arrays on huge pages under any other
//! allocator, the library's users' and the tests' included.

use bytemuck::Pod;
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicBool, Ordering};

/// Arrays smaller than this stay in a `Vec` (a huge page is 2 MiB).
pub const HUGE_MIN_BYTES: usize = 4 << 20;

/// Whether the process's allocator puts its mappings on huge pages.
static ALLOCATOR_HUGE: AtomicBool = AtomicBool::new(false);

/// Tells `Pages` that the global allocator already advises its mappings
/// as huge pages (the `whitted` binary's jemalloc, `thp:always`), so an
/// array is kept in its `Vec` rather than copied (on 1 M spheres, 112 MB
/// of primitives and grid references: BENCHMARKS.md, "Packing large
/// scenes").
pub fn allocator_gives_huge_pages() {
    ALLOCATOR_HUGE.store(true, Ordering::Relaxed);
}

/// A fixed-length array of plain data; derefs to a slice.
pub struct Pages<T: Pod> {
    store: Store<T>,
}

enum Store<T> {
    Vec(Vec<T>),
    Map { map: memmap2::MmapMut, len: usize },
}

impl<T: Pod> Pages<T> {
    /// True when the array lives in a mapping advised to use huge pages.
    pub fn huge(&self) -> bool {
        matches!(self.store, Store::Map { .. })
    }

    pub fn as_slice(&self) -> &[T] {
        self
    }
}

impl<T: Pod> From<Vec<T>> for Pages<T> {
    fn from(v: Vec<T>) -> Self {
        let bytes = std::mem::size_of_val(v.as_slice());
        if bytes < HUGE_MIN_BYTES || ALLOCATOR_HUGE.load(Ordering::Relaxed) {
            return Pages {
                store: Store::Vec(v),
            };
        }
        // A failed mapping (no memory for a second copy) keeps the Vec.
        let Ok(mut map) = memmap2::MmapMut::map_anon(bytes) else {
            return Pages {
                store: Store::Vec(v),
            };
        };
        // Advice only: where the kernel has no THP the mapping still works.
        #[cfg(target_os = "linux")]
        let _ = map.advise(memmap2::Advice::HugePage);
        map.copy_from_slice(bytemuck::cast_slice(&v));
        Pages {
            store: Store::Map { map, len: v.len() },
        }
    }
}

impl<T: Pod> Deref for Pages<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.store {
            Store::Vec(v) => v,
            // The mapping is page-aligned (alignment of any Pod type) and
            // exactly len elements long.
            Store::Map { map, len } => bytemuck::cast_slice(&map[..len * std::mem::size_of::<T>()]),
        }
    }
}

impl<T: Pod> DerefMut for Pages<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        match &mut self.store {
            Store::Vec(v) => v,
            Store::Map { map, len } => {
                bytemuck::cast_slice_mut(&mut map[..*len * std::mem::size_of::<T>()])
            }
        }
    }
}

impl<T: Pod> Default for Pages<T> {
    fn default() -> Self {
        Vec::new().into()
    }
}

impl<T: Pod> Clone for Pages<T> {
    fn clone(&self) -> Self {
        self.to_vec().into()
    }
}

impl<T: Pod + std::fmt::Debug> std::fmt::Debug for Pages<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pages")
            .field("len", &self.len())
            .field("huge", &self.huge())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_arrays_stay_in_a_vec_and_large_ones_map_with_the_same_contents() {
        let small: Pages<u32> = (0..1000u32).collect::<Vec<_>>().into();
        assert!(!small.huge());
        assert_eq!(small[999], 999);
        let n = HUGE_MIN_BYTES / 4 + 3;
        let v: Vec<u32> = (0..n as u32)
            .map(|i| i.wrapping_mul(2_654_435_761))
            .collect();
        let mut big: Pages<u32> = v.clone().into();
        assert!(big.huge());
        assert_eq!(big.len(), n);
        assert_eq!(&big[..], &v[..]);
        big[n - 1] = 7;
        assert_eq!(big.clone()[n - 1], 7);
        assert_eq!(Pages::<u32>::default().len(), 0);
    }
}
