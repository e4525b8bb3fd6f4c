//! `frond`, the operator's command. Thin: parse, run, map errors to exit codes.

use std::process::ExitCode;

/// Counts allocations only on a thread inside `frond bench`'s measurement; otherwise one relaxed
/// load per allocation on top of the system allocator.
#[global_allocator]
static ALLOCATOR: frond_bench::alloc::CountingAlloc = frond_bench::alloc::CountingAlloc;

fn main() -> ExitCode {
    frond_cli::main_with_args(std::env::args_os())
}
