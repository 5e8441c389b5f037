#pragma once
// Copies of megabytes spread over the cores: the readback's planes out of host-cached memory and
// the near tier's work lists into device memory the host writes directly (resizable BAR), which
// is write-combined: one core fills it at a fraction of the bus's rate.
#include <cstddef>
#include <initializer_list>
#include <span>

namespace voxtier {

/// One copy: `bytes` from `from` to `to` (the ranges do not overlap).
struct CopyPiece {
    void* to = nullptr;
    const void* from = nullptr;
    std::size_t bytes = 0;
};

/// Copies every piece, in chunks of 256 KiB spread over the cores: large enough that a task's
/// overhead vanishes, small enough that a 2 MB plane keeps 8 cores busy. Each destination byte
/// is stored once, in address order within its chunk (what write-combined memory wants).
void copyInParallel(std::span<const CopyPiece> pieces);

/// The same, for a list written in place.
inline void copyInParallel(std::initializer_list<CopyPiece> pieces) {
    copyInParallel(std::span<const CopyPiece>(pieces.begin(), pieces.size()));
}

} // namespace voxtier
