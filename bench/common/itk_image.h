#pragma once
//! \file
//! \brief lobe images as ITK images, for the benchmarks' ITK peers. Include it only from a file
//! compiled with ITK's include directories (bench/seg/itk_peer.cpp, bench/mr/n4_peer.cpp).

#include "lobe/core/image3d.h"

#include <itkImage.h>
#include <vnl/algo/vnl_determinant.h>

#include <cmath>
#include <cstddef>

namespace lobe::bench {

//! The lobe grid as an ITK image of dimension D (D = 2 takes the first two axes of a one-slice
//! image). `convert` maps each lobe value to the ITK pixel.
template <class ItkImage, class T, class Convert>
typename ItkImage::Pointer to_itk(const core::Image3D<T>& img, Convert convert)
{
    constexpr unsigned D = ItkImage::ImageDimension;
    typename ItkImage::SizeType size;
    typename ItkImage::SpacingType spacing;
    typename ItkImage::PointType origin;
    typename ItkImage::DirectionType direction;
    for (unsigned a = 0; a < D; ++a) {
        size[a] = static_cast<itk::SizeValueType>(img.size[a]);
        spacing[a] = img.spacing[a];
        origin[a] = img.origin[a];
        for (unsigned b = 0; b < D; ++b)
            direction(a, b) = img.direction[3 * a + b];
    }
    if (std::abs(vnl_determinant(direction.GetVnlMatrix())) < 1e-3) // an oblique slice's 2x2 block
        direction.SetIdentity();
    auto out = ItkImage::New();
    typename ItkImage::RegionType region;
    region.SetSize(size);
    out->SetRegions(region);
    out->SetSpacing(spacing);
    out->SetOrigin(origin);
    out->SetDirection(direction);
    out->Allocate();
    auto* p = out->GetBufferPointer();
    for (std::size_t i = 0; i < img.data.size(); ++i)
        p[i] = convert(img.data[i]);
    return out;
}

} // namespace lobe::bench
