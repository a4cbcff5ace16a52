#pragma once
// Large columns (millions of samples) backed by transparent huge pages where the kernel offers them only on request
// (THP mode "madvise", as Debian and most virtual machines run). Each first touch of a 4 KiB page is a page fault,
// and on a virtual machine a fault costs several microseconds: a million-row import faults in 40 MB of columns, ten
// thousand faults and more than the parsing itself. A 2 MiB page takes one fault for 512 of them.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <sys/mman.h>

namespace feedid {

/// Asks for huge pages under the reserved storage of `column` (the whole 2 MiB pages inside it; the ends stay small
/// pages). A hint: without THP, or for columns under a few MiB, nothing changes. Call it right after `reserve`,
/// before the storage is written.
template <class T>
void prefer_huge_pages(const std::vector<T>& column) {
    constexpr std::uintptr_t huge = std::uintptr_t{2} << 20;
    const auto begin = reinterpret_cast<std::uintptr_t>(column.data());
    const auto end = begin + column.capacity() * sizeof(T);
    const std::uintptr_t first = (begin + huge - 1) & ~(huge - 1);
    const std::uintptr_t last = end & ~(huge - 1);
    if (column.data() == nullptr || last <= first) return;
    ::madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
}

}  // namespace feedid
