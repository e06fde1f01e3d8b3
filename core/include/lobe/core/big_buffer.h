#pragma once
//! \file
//! \brief BigBufferAllocator: the allocator of image voxel buffers; on Linux, buffers of 4 MiB
//! and more are backed by transparent huge pages.
//!
//! Why: a 512 x 512 x 200 volume is 200 MB a float image, and `lseg liver` creates a dozen such
//! images. Fresh memory costs a page fault per 4 KiB page on first touch, and in a virtual
//! machine each fault is expensive: on the 2-core KVM machine of docs/benchmarks.md, faults and
//! the kernel's page clearing took about a fifth of `lseg liver`'s samples. Where the kernel
//! hands out huge pages only on request (`/sys/kernel/mm/transparent_hugepage/enabled` =
//! `madvise`, Debian's default), asking for them takes one fault per 2 MiB instead of 512.
//! Smaller buffers (a 512 x 512 float slice is 1 MiB) stay with plain malloc: a huge page
//! would round them up and clear the difference. Elsewhere (no THP, another OS) this is
//! malloc with a 2 MiB alignment for big buffers.

#include <cstddef>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace lobe::core {

template <class T>
struct BigBufferAllocator {
    using value_type = T;

    static constexpr std::size_t kHugePage = std::size_t{2} << 20; //!< x86-64's and arm64's THP size
    static constexpr std::size_t kThreshold = std::size_t{4} << 20; //!< smallest buffer sent to huge pages

    BigBufferAllocator() noexcept = default;
    template <class U>
    BigBufferAllocator(const BigBufferAllocator<U>&) noexcept // NOLINT(google-explicit-constructor)
    {
    }

    T* allocate(std::size_t n)
    {
        if (n > std::numeric_limits<std::size_t>::max() / sizeof(T))
            throw std::bad_array_new_length();
        const std::size_t bytes = n * sizeof(T);
        if (bytes < kThreshold) {
            // malloc rather than std::allocator so that deallocate frees both kinds alike.
            void* p = std::malloc(bytes == 0 ? 1 : bytes);
            if (!p)
                throw std::bad_alloc();
            return static_cast<T*>(p);
        }
        const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
        void* p = std::aligned_alloc(kHugePage, rounded);
        if (!p)
            throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        ::madvise(p, rounded, MADV_HUGEPAGE); // advice only: a kernel without THP says EINVAL, harmlessly
#endif
        return static_cast<T*>(p);
    }

    void deallocate(T* p, std::size_t) noexcept { std::free(p); }

    template <class U>
    bool operator==(const BigBufferAllocator<U>&) const noexcept
    {
        return true;
    }
    template <class U>
    bool operator!=(const BigBufferAllocator<U>&) const noexcept
    {
        return false;
    }
};

} // namespace lobe::core

namespace lobe::core {

//! A vector of voxel values with the big-buffer allocator: the type of Image3D::data.
template <class T>
using BigVector = std::vector<T, BigBufferAllocator<T>>;

} // namespace lobe::core
