//! Memory for the arrays the fast engine's step streams through (the state and the spring
//! groups), asked of the operating system in 2 MiB pages where it gives them.
//!
//! Why: with 4 KiB pages an explicit step at 100k nodes walks about 7,000 pages of spring
//! groups and state, and every first touch of a page whose translation is not cached costs a
//! page-table walk, which under a hypervisor's nested paging reads up to 24 entries. Backing
//! the same arrays with 2 MiB pages made the peers' 100k-node box step 1-7% faster damped and
//! 10-13% undamped on the 2-core test machine (docs/measurements.md, twelfth slice).
//!
//! How: arrays of at least [`LARGE`] bytes are mapped on their own, aligned to and rounded up
//! to 2 MiB, and advised `MADV_HUGEPAGE` before their first touch, so that Linux's
//! transparent huge pages back them whether the system's mode is `always` or `madvise` (the
//! common default, where nothing else asks for them). Smaller arrays, and every array on
//! other systems, come from the global allocator as any `Vec`'s. The advice is a request:
//! where the kernel has no free 2 MiB page the array is backed by 4 KiB pages as before,
//! though a kernel set to defragment for advised memory (`defrag` `madvise`, the usual
//! default) may first spend time compacting. That happens where a large array is first
//! written: when the engine is built, and when a patch outgrows an array's spare room (which
//! copies the array anyway; growing a small array still reallocates in place where it can).
//!
//! The arrays are `allocator_api2`'s `Vec` with this allocator: the standard `Vec`'s API on
//! stable Rust, so the engine's code that grows and patches them is unchanged.

use allocator_api2::alloc::{AllocError, Allocator, Global, Layout};
use std::ptr::NonNull;

/// A huge page of x86-64 and aarch64 Linux with 4 KiB base pages.
pub(super) const HUGE: usize = 2 << 20;

/// Arrays of at least this many bytes get pages of their own (half a huge page: the
/// rounding wastes at most as much as the array holds).
pub(super) const LARGE: usize = HUGE / 2;

/// The allocator of the step's arrays (see the module's documentation).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Pages;

/// A vector whose buffer [`Pages`] allocates.
pub(super) type PageVec<T> = allocator_api2::vec::Vec<T, Pages>;

/// An empty [`PageVec`] with room for `capacity` entries.
pub(super) fn with_capacity<T>(capacity: usize) -> PageVec<T> {
    PageVec::with_capacity_in(capacity, Pages)
}

/// (capacity, length, bytes per entry) of a growable array, for a patch's growth report.
pub(super) trait Room {
    fn room(&self) -> (usize, usize, usize);
}

impl<T> Room for Vec<T> {
    fn room(&self) -> (usize, usize, usize) {
        (self.capacity(), self.len(), std::mem::size_of::<T>())
    }
}

impl<T> Room for PageVec<T> {
    fn room(&self) -> (usize, usize, usize) {
        (self.capacity(), self.len(), std::mem::size_of::<T>())
    }
}

/// Whether a block of `layout` is mapped on its own pages.
fn is_large(layout: Layout) -> bool {
    cfg!(target_os = "linux") && layout.size() >= LARGE && layout.align() <= HUGE
}

/// `layout`'s size rounded up to whole huge pages.
#[cfg(target_os = "linux")]
fn mapped_len(layout: Layout) -> usize {
    layout.size().div_ceil(HUGE) * HUGE
}

// SAFETY: a block from `allocate` stays valid until `deallocate` (its pages are mapped until
// then), copies of `Pages` are interchangeable (it has no state), and `deallocate` takes the
// same branch and length for a layout `allocate` took (both are functions of the layout).
unsafe impl Allocator for Pages {
    fn allocate(&self, layout: Layout) -> Result<NonNull<[u8]>, AllocError> {
        if !is_large(layout) {
            return Global.allocate(layout);
        }
        #[cfg(target_os = "linux")]
        {
            let len = mapped_len(layout);
            let p = map_aligned(len).ok_or(AllocError)?;
            Ok(NonNull::slice_from_raw_parts(p, layout.size()))
        }
        #[cfg(not(target_os = "linux"))]
        unreachable!("only Linux maps large arrays on their own")
    }

    unsafe fn grow(
        &self,
        ptr: NonNull<u8>,
        old: Layout,
        new: Layout,
    ) -> Result<NonNull<[u8]>, AllocError> {
        if !is_large(old) && !is_large(new) {
            // SAFETY: the caller's; both blocks are the global allocator's.
            return unsafe { Global.grow(ptr, old, new) };
        }
        // SAFETY: the caller's: `ptr` holds `old.size()` bytes, no more than `new` takes.
        unsafe { self.moved(ptr, old, new, old.size()) }
    }

    unsafe fn shrink(
        &self,
        ptr: NonNull<u8>,
        old: Layout,
        new: Layout,
    ) -> Result<NonNull<[u8]>, AllocError> {
        if !is_large(old) && !is_large(new) {
            // SAFETY: the caller's; both blocks are the global allocator's.
            return unsafe { Global.shrink(ptr, old, new) };
        }
        // SAFETY: the caller's: `ptr` holds at least the `new.size()` bytes kept.
        unsafe { self.moved(ptr, old, new, new.size()) }
    }

    unsafe fn deallocate(&self, ptr: NonNull<u8>, layout: Layout) {
        if !is_large(layout) {
            // SAFETY: the caller's; `allocate` took the global allocator for this layout.
            return unsafe { Global.deallocate(ptr, layout) };
        }
        #[cfg(target_os = "linux")]
        // SAFETY: `allocate` mapped exactly this range for this layout.
        unsafe {
            libc::munmap(ptr.as_ptr().cast(), mapped_len(layout));
        }
    }
}

impl Pages {
    /// The block `ptr` of layout `old` moved to a new block of layout `new` (mapped, or the
    /// global allocator's), its first `bytes` copied and the old block freed: the trait's own
    /// `grow` and `shrink`, for a move to or from a mapping of its own.
    ///
    /// # Safety
    /// `ptr` is a block of this allocator with layout `old`, holding at least `bytes`, and
    /// `bytes` is at most `new.size()`.
    unsafe fn moved(
        &self,
        ptr: NonNull<u8>,
        old: Layout,
        new: Layout,
        bytes: usize,
    ) -> Result<NonNull<[u8]>, AllocError> {
        let block = self.allocate(new)?;
        // SAFETY: the caller's; the new block is distinct from the old.
        unsafe {
            std::ptr::copy_nonoverlapping(ptr.as_ptr(), block.cast::<u8>().as_ptr(), bytes);
            self.deallocate(ptr, old);
        }
        Ok(block)
    }
}

/// `len` bytes (a multiple of [`HUGE`]) of fresh, zeroed anonymous memory starting on a
/// [`HUGE`] boundary, advised `MADV_HUGEPAGE`; `None` where the system has no room.
#[cfg(target_os = "linux")]
fn map_aligned(len: usize) -> Option<NonNull<u8>> {
    use libc::{c_void, MAP_ANONYMOUS, MAP_FAILED, MAP_PRIVATE, PROT_READ, PROT_WRITE};
    // Map a huge page more than asked and unmap the ends that fall outside the aligned range.
    let span = len.checked_add(HUGE)?;
    // SAFETY: a new private anonymous mapping; nothing else refers to it.
    let base = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            span,
            PROT_READ | PROT_WRITE,
            MAP_PRIVATE | MAP_ANONYMOUS,
            -1,
            0,
        )
    };
    if base == MAP_FAILED {
        return None;
    }
    let head = (base as usize).next_multiple_of(HUGE) - base as usize;
    let tail = span - head - len;
    let start = base.cast::<u8>().wrapping_add(head);
    // SAFETY: both ranges lie within the mapping just made, outside the part kept; the advice
    // only asks for larger pages (a kernel without transparent huge pages refuses it, and the
    // memory stays usable).
    unsafe {
        if head > 0 {
            libc::munmap(base, head);
        }
        if tail > 0 {
            libc::munmap(start.wrapping_add(len).cast::<c_void>(), tail);
        }
        libc::madvise(start.cast::<c_void>(), len, libc::MADV_HUGEPAGE);
    }
    NonNull::new(start)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mappings of this process that overlap `range`, as (start, end, flags); `None`
    /// where `/proc/self/smaps` cannot be read.
    #[cfg(target_os = "linux")]
    fn mappings_over(range: std::ops::Range<usize>) -> Option<Vec<(usize, usize, Vec<String>)>> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut out = Vec::new();
        let mut current: Option<(usize, usize)> = None;
        for line in smaps.lines() {
            // A mapping's header: `lo-hi perms ...`, hex addresses.
            let header = line.split_once(' ').and_then(|(r, _)| r.split_once('-'));
            if let Some((lo, hi)) = header {
                if let (Ok(lo), Ok(hi)) =
                    (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
                {
                    current = (lo < range.end && range.start < hi).then_some((lo, hi));
                    continue;
                }
            }
            if let (Some((lo, hi)), Some(f)) = (current, line.strip_prefix("VmFlags:")) {
                out.push((lo, hi, f.split_whitespace().map(str::to_owned).collect()));
            }
        }
        Some(out)
    }

    /// The tests that map and unmap large arrays, one at a time: `cargo test` runs tests on
    /// threads of one process, and one test's new mapping could land where another's was.
    static MAPPING: std::sync::Mutex<()> = std::sync::Mutex::new(());

    #[test]
    fn arrays_keep_their_entries_across_the_small_and_large_allocations() {
        let _one = MAPPING.lock();
        // From the global allocator to a mapping of its own and back, through growth and
        // shrinking in each: the entries stay.
        let mut v: PageVec<[f32; 4]> = with_capacity(16);
        v.extend((0..16).map(|i| [i as f32; 4]));
        v.reserve(LARGE / 16);
        assert!(is_large(Layout::array::<[f32; 4]>(v.capacity()).unwrap()));
        if cfg!(target_os = "linux") {
            assert_eq!(
                v.as_ptr() as usize % HUGE,
                0,
                "a large array starts a huge page"
            );
        }
        let n = v.capacity();
        v.extend((16..n).map(|i| [i as f32; 4]));
        v.push([n as f32; 4]);
        assert!(v.capacity() > n, "grown from one mapping to another");
        v.truncate(LARGE / 16 + 10);
        v.shrink_to_fit();
        assert!(is_large(Layout::array::<[f32; 4]>(v.capacity()).unwrap()));
        v.truncate(100);
        v.shrink_to_fit();
        assert!(!is_large(Layout::array::<[f32; 4]>(v.capacity()).unwrap()));
        assert!(v.iter().enumerate().all(|(i, r)| *r == [i as f32; 4]));
        let copy = v.clone();
        assert_eq!(&copy[..], &v[..]);
        // Exactly `LARGE` bytes is large.
        let edge: PageVec<u8> = with_capacity(LARGE);
        if cfg!(target_os = "linux") {
            assert_eq!(edge.as_ptr() as usize % HUGE, 0);
        }
    }

    /// A dropped large array gives its whole mapping back (no part of it left mapped).
    #[test]
    #[cfg(target_os = "linux")]
    fn a_dropped_large_array_is_unmapped() {
        let _one = MAPPING.lock();
        let v: PageVec<u8> = with_capacity(3 * HUGE + 1);
        let range = v.as_ptr() as usize..v.as_ptr() as usize + 4 * HUGE;
        let Some(before) = mappings_over(range.clone()) else {
            eprintln!("skipped: /proc/self/smaps cannot be read here");
            return;
        };
        assert!(before
            .iter()
            .any(|(lo, hi, _)| *lo <= range.start && range.end <= *hi));
        drop(v);
        // Nothing advised for huge pages left over the range (the global allocator's memory,
        // which other threads may map there since, is not advised).
        let after = mappings_over(range).unwrap();
        assert!(
            !after.iter().any(|(_, _, f)| f.iter().any(|f| f == "hg")),
            "{after:?}"
        );
    }

    /// The engine's step arrays come from [`Pages`]: a mesh whose spring groups pass
    /// [`LARGE`] has them on a huge-page boundary, and growing them (as a patch that appends
    /// slices past their room does) keeps them there.
    #[test]
    fn the_fast_engines_spring_groups_start_a_huge_page() {
        let _one = MAPPING.lock();
        use crate::engine::fast::FastEngine;
        use crate::engine::{Engine, SimConfig};
        use crate::mesh::generate::BoxGrid;
        use crate::model::{stable_time_step, Material, ModelConfig, SpringModel};
        let mesh = BoxGrid::cube_cells([17, 17, 17], 0.01).build().unwrap();
        let model = SpringModel::build(&mesh, &ModelConfig::new(Material::elastic(5e3, 0.3, 1e3)))
            .unwrap()
            .pack(&mesh)
            .unwrap();
        let mut engine = FastEngine::new(&model, SimConfig::new(0.3 * stable_time_step(&model).dt));
        let groups = &engine.graph.springs.groups;
        let bytes = std::mem::size_of_val(&groups[..]);
        assert!(
            bytes >= LARGE,
            "{bytes} B of groups: the test needs a larger mesh"
        );
        if cfg!(target_os = "linux") {
            assert_eq!(groups.as_ptr() as usize % HUGE, 0);
        }
        // Grown past its room (as a patch that appends slices does): still on a boundary.
        let g = &mut engine.graph.springs.groups;
        g.reserve(g.capacity() + 1);
        if cfg!(target_os = "linux") {
            assert_eq!(g.as_ptr() as usize % HUGE, 0);
        }
        engine.step(2);
        assert!(engine.positions().iter().flatten().all(|c| c.is_finite()));
    }

    /// The advice is recorded on the mapping (`hg` in its `VmFlags`), whatever pages the
    /// kernel then finds: a test that holds on any Linux with transparent huge pages.
    #[test]
    #[cfg(target_os = "linux")]
    fn large_arrays_are_advised_huge_pages() {
        let _one = MAPPING.lock();
        let mode = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled");
        if mode.as_deref().map_or(true, |m| m.contains("[never]")) {
            eprintln!("skipped: this kernel has no transparent huge pages ({mode:?})");
            return;
        }
        let mut v: PageVec<u8> = with_capacity(4 * HUGE);
        v.resize(4 * HUGE, 1);
        let at = v.as_ptr() as usize;
        let Some(maps) = mappings_over(at..at + 1) else {
            eprintln!("skipped: /proc/self/smaps cannot be read here");
            return;
        };
        let (_, _, flags) = maps.first().expect("the array's mapping is listed");
        assert!(flags.iter().any(|f| f == "hg"), "{flags:?}");
    }
}
