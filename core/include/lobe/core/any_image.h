#pragma once
//! \file
//! \brief AnyImage: an Image3D of any pixel type a CT, MRI or label file uses, as a variant.
//!
//! Readers return AnyImage so that no file is silently converted; callers pick the type they
//! compute in with convert_image<T>().

#include "lobe/core/image3d.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

namespace lobe::core {

//! Pixel types, in MetaImage's vocabulary (MET_UCHAR ... MET_DOUBLE).
enum class PixelType { UInt8, Int8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

using AnyImage = std::variant<Image3D<std::uint8_t>, Image3D<std::int8_t>, Image3D<std::int16_t>,
                              Image3D<std::uint16_t>, Image3D<std::int32_t>, Image3D<std::uint32_t>,
                              Image3D<float>, Image3D<double>>;

template <class T> constexpr PixelType pixel_type_of();
template <> constexpr PixelType pixel_type_of<std::uint8_t>() { return PixelType::UInt8; }
template <> constexpr PixelType pixel_type_of<std::int8_t>() { return PixelType::Int8; }
template <> constexpr PixelType pixel_type_of<std::int16_t>() { return PixelType::Int16; }
template <> constexpr PixelType pixel_type_of<std::uint16_t>() { return PixelType::UInt16; }
template <> constexpr PixelType pixel_type_of<std::int32_t>() { return PixelType::Int32; }
template <> constexpr PixelType pixel_type_of<std::uint32_t>() { return PixelType::UInt32; }
template <> constexpr PixelType pixel_type_of<float>() { return PixelType::Float32; }
template <> constexpr PixelType pixel_type_of<double>() { return PixelType::Float64; }

inline PixelType pixel_type(const AnyImage& img)
{
    return std::visit([](const auto& im) { return pixel_type_of<typename std::decay_t<decltype(im)>::value_type>(); },
                      img);
}

//! Bytes per pixel.
inline int pixel_size(PixelType t)
{
    switch (t) {
    case PixelType::UInt8: case PixelType::Int8: return 1;
    case PixelType::Int16: case PixelType::UInt16: return 2;
    case PixelType::Int32: case PixelType::UInt32: case PixelType::Float32: return 4;
    case PixelType::Float64: return 8;
    }
    return 0;
}

//! Short lower-case name ("uint8", "int16", "float32", ...), used in HDF5 attributes and reports.
inline const char* pixel_type_name(PixelType t)
{
    switch (t) {
    case PixelType::UInt8: return "uint8";
    case PixelType::Int8: return "int8";
    case PixelType::Int16: return "int16";
    case PixelType::UInt16: return "uint16";
    case PixelType::Int32: return "int32";
    case PixelType::UInt32: return "uint32";
    case PixelType::Float32: return "float32";
    case PixelType::Float64: return "float64";
    }
    return "unknown";
}

//! An empty image of pixel type `t` on grid `g`, zero-filled.
inline AnyImage make_image(PixelType t, const ImageGeometry& g)
{
    switch (t) {
    case PixelType::UInt8: return Image3D<std::uint8_t>(g);
    case PixelType::Int8: return Image3D<std::int8_t>(g);
    case PixelType::Int16: return Image3D<std::int16_t>(g);
    case PixelType::UInt16: return Image3D<std::uint16_t>(g);
    case PixelType::Int32: return Image3D<std::int32_t>(g);
    case PixelType::UInt32: return Image3D<std::uint32_t>(g);
    case PixelType::Float32: return Image3D<float>(g);
    case PixelType::Float64: return Image3D<double>(g);
    }
    throw InvalidInputError("make_image: unknown pixel type");
}

inline const ImageGeometry& geometry(const AnyImage& img)
{
    return std::visit([](const auto& im) -> const ImageGeometry& { return im; }, img);
}
inline ImageGeometry& geometry(AnyImage& img)
{
    return std::visit([](auto& im) -> ImageGeometry& { return im; }, img);
}

//! Minimum and maximum pixel value as doubles ({0, 0} for an empty image; NaNs are skipped).
inline std::pair<double, double> value_range(const AnyImage& img)
{
    return std::visit(
        [](const auto& im) {
            double lo = std::numeric_limits<double>::infinity(), hi = -lo;
            for (const auto v : im.data) {
                const double d = static_cast<double>(v);
                if (d < lo) lo = d;
                if (d > hi) hi = d;
            }
            return lo <= hi ? std::pair<double, double>{lo, hi} : std::pair<double, double>{0.0, 0.0};
        },
        img);
}

//! Converts a value to T, rounding to nearest and saturating for integer T (NaN becomes 0).
template <class T, class S>
T saturate_cast(S v)
{
    if constexpr (std::is_floating_point_v<T>) {
        return static_cast<T>(v);
    } else if constexpr (std::is_floating_point_v<S>) {
        if (std::isnan(v)) return T{0};
        const double r = std::nearbyint(static_cast<double>(v));
        if (r <= static_cast<double>(std::numeric_limits<T>::lowest())) return std::numeric_limits<T>::lowest();
        if (r >= static_cast<double>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
        return static_cast<T>(r);
    } else {
        using W = long long;
        const W w = static_cast<W>(v);
        if constexpr (std::is_unsigned_v<S> && sizeof(S) >= sizeof(W)) {
            if (v > static_cast<S>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
        }
        if (w < static_cast<W>(std::numeric_limits<T>::lowest())) return std::numeric_limits<T>::lowest();
        if (w > static_cast<W>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
        return static_cast<T>(w);
    }
}

//! The image with its pixels converted to T (saturating, see saturate_cast); same geometry.
template <class T>
Image3D<T> convert_image(const AnyImage& img)
{
    return std::visit(
        [](const auto& im) {
            using S = typename std::decay_t<decltype(im)>::value_type;
            if constexpr (std::is_same_v<S, T>) {
                return im;
            } else {
                Image3D<T> out;
                static_cast<ImageGeometry&>(out) = im;
                out.data.resize(im.data.size());
                std::transform(im.data.begin(), im.data.end(), out.data.begin(),
                               [](S v) { return saturate_cast<T>(v); });
                return out;
            }
        },
        img);
}

} // namespace lobe::core
