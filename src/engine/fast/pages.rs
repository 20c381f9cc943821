//! Memory for the arrays the fast engine's step streams through (the state and the spring
//! groups), asked of the operating system in 2 MiB pages where it gives them.
//!
//! Why: with 4 KiB pages an explicit step at 100k nodes walks about 7,000 pages of spring
//! groups and state, and every first touch of a page whose translation is not cached costs a
//! page-table walk, which under a hypervisor's nested paging reads up to 24 entries. Backing
//! the same arrays with 2 MiB pages made the peers' 100k-node box step 7-14% faster on the
//! 2-core test machine (docs/measurements.md, twelfth slice).
//!
//! How: arrays of at least [`LARGE`] bytes are mapped on their own, aligned to and rounded up
//! to 2 MiB, and advised `MADV_HUGEPAGE` before their first touch, so that Linux's
//! transparent huge pages back them whether the system's mode is `always` or `madvise` (the
//! common default, where nothing else asks for them). Smaller arrays, and every array on
//! other systems, come from the global allocator as any `Vec`'s. The advice is a request:
//! where the kernel has no free 2 MiB page the array is backed by 4 KiB pages as before.
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
    let start = (base as usize).next_multiple_of(HUGE);
    let (head, tail) = (start - base as usize, span - (start - base as usize) - len);
    // SAFETY: both ranges lie within the mapping just made, outside the part kept; the advice
    // only asks for larger pages (a kernel without transparent huge pages refuses it, and the
    // memory stays usable).
    unsafe {
        if head > 0 {
            libc::munmap(base, head);
        }
        if tail > 0 {
            libc::munmap((start + len) as *mut c_void, tail);
        }
        libc::madvise(start as *mut c_void, len, libc::MADV_HUGEPAGE);
    }
    NonNull::new(start as *mut u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_arrays_come_from_the_global_allocator_and_large_ones_are_aligned() {
        let small: PageVec<u64> = with_capacity(16);
        assert!(!is_large(Layout::array::<u64>(small.capacity()).unwrap()));
        let mut large: PageVec<[f32; 4]> = with_capacity(LARGE / 16 + 1);
        if cfg!(target_os = "linux") {
            assert_eq!(
                large.as_ptr() as usize % HUGE,
                0,
                "a large array starts a huge page"
            );
        }
        // Filled, grown past its room (a new mapping and a copy), shrunk: the entries stay.
        let n = large.capacity();
        large.extend((0..n).map(|i| [i as f32; 4]));
        large.push([-1.0; 4]);
        assert!(large.capacity() > n);
        large.truncate(LARGE / 64);
        large.shrink_to_fit();
        assert!(large.capacity() < LARGE / 16);
        assert!(large.iter().enumerate().all(|(i, r)| r[0] == i as f32));
        let copy = large.clone();
        assert_eq!(&copy[..], &large[..]);
    }

    /// The engine's step arrays come from [`Pages`]: a mesh whose spring groups pass
    /// [`LARGE`] has them on a huge-page boundary, and a cut that grows them keeps them there.
    #[test]
    fn the_fast_engines_spring_groups_start_a_huge_page() {
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
        let mode = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled");
        if mode.as_deref().map_or(true, |m| m.contains("[never]")) {
            eprintln!("skipped: this kernel has no transparent huge pages ({mode:?})");
            return;
        }
        let mut v: PageVec<u8> = with_capacity(4 * HUGE);
        v.resize(4 * HUGE, 1);
        let at = v.as_ptr() as usize;
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        // The mapping holding `at`: its header line is `lo-hi perms ...`, hex addresses.
        let mut inside = false;
        let mut flags = None;
        for line in smaps.lines() {
            if let Some((range, _)) = line.split_once(' ') {
                if let Some((lo, hi)) = range.split_once('-') {
                    if let (Ok(lo), Ok(hi)) =
                        (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
                    {
                        inside = (lo..hi).contains(&at);
                        continue;
                    }
                }
            }
            if inside {
                if let Some(f) = line.strip_prefix("VmFlags:") {
                    flags = Some(f.split_whitespace().map(str::to_owned).collect::<Vec<_>>());
                }
            }
        }
        let flags = flags.expect("the array's mapping is listed");
        assert!(flags.iter().any(|f| f == "hg"), "{flags:?}");
    }
}
