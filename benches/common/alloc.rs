//! The `spindlelab` binary's global allocator (mimalloc, see `src/main.rs`), so a bench measures
//! the kernels as the command runs them.

#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;
