//! The `flatbake` binary: the command line over the `flatbake-core` library.

mod cli;
mod flags;
mod legend;
mod plot;
mod shard;
mod watch;

fn main() -> std::process::ExitCode {
    keep_large_buffers_mapped();
    cli::main()
}

/// glibc's malloc serves blocks of 128 KiB and more with their own mappings,
/// but raises that threshold (up to 32 MiB) each time such a block is
/// freed. After the form factors free theirs, the gather's per-pixel arrays
/// would then come from the heap, where the freed memory of the earlier
/// stages stays resident: the 2048 px benchmark peaked at 505 MB instead of
/// 408 MB. A fixed threshold keeps every large buffer in its own mapping,
/// returned to the system when it is freed.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn keep_large_buffers_mapped() {
    // SAFETY: mallopt only sets an allocator parameter; it is called before
    // any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 * 1024);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_large_buffers_mapped() {}
