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
//! Smaller buffers (a 512 x 512 float slice is 1 MiB) get no advice: a huge page would round
//! them up and clear the difference. Elsewhere (no THP, another OS) this is plain malloc.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace lobe::core {

template <class T>
struct BigBufferAllocator {
    using value_type = T;

    static constexpr std::size_t kPage = 4096; //!< madvise's granularity (the smallest page size)
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
        void* p = std::malloc(bytes == 0 ? 1 : bytes);
        if (!p)
            throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (bytes >= kThreshold) {
            // The advice covers the whole pages inside the buffer; the kernel backs every 2 MiB
            // aligned block among them with a huge page, so at most the first and last 2 MiB
            // stay on small pages. Not aligning the buffer itself is deliberate: an aligned
            // request asks glibc for 2 MiB more than a freed buffer of the same size holds, so
            // freed buffers were never reused and a 3-D snake's peak memory grew by half.
            const auto first = (reinterpret_cast<std::uintptr_t>(p) + kPage - 1) / kPage * kPage;
            const auto last = (reinterpret_cast<std::uintptr_t>(p) + bytes) / kPage * kPage;
            // advice only: a kernel without THP says EINVAL, harmlessly
            ::madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
        }
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

//! A vector of voxel values with the big-buffer allocator: the type of Image3D::data.
template <class T>
using BigVector = std::vector<T, BigBufferAllocator<T>>;

} // namespace lobe::core
