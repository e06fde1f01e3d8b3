#pragma once
// Comparing the PNG pictures the tools write, decoded with OpenCV.

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <string>

namespace lobe::test {

//! The rows at the bottom of a captioned picture that hold its caption (tools/common/picture.cpp).
inline constexpr int kCaptionRows = 22;

//! "" when the pictures at `a` and `b` have the same size and the same pixels above their caption
//! strips, else what differs (the captions may differ: they name the voxel index of the slice).
inline std::string picture_difference_above_caption(const std::filesystem::path& a, const std::filesystem::path& b)
{
    const cv::Mat pa = cv::imread(a.string(), cv::IMREAD_COLOR), pb = cv::imread(b.string(), cv::IMREAD_COLOR);
    if (pa.empty() || pb.empty())
        return "cannot read " + (pa.empty() ? a : b).string();
    if (pa.size() != pb.size())
        return "sizes differ: " + std::to_string(pa.cols) + " x " + std::to_string(pa.rows) + " against " +
               std::to_string(pb.cols) + " x " + std::to_string(pb.rows);
    if (pa.rows <= kCaptionRows)
        return "no room for a caption";
    const cv::Rect above(0, 0, pa.cols, pa.rows - kCaptionRows);
    cv::Mat diff;
    cv::absdiff(pa(above), pb(above), diff);
    const int pixels = cv::countNonZero(diff.reshape(1));
    return pixels == 0 ? "" : std::to_string(pixels) + " channel values differ above the caption";
}

} // namespace lobe::test
