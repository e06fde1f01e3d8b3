#include "common/picture.h"

#include "common/files.h"

#include "lobe/core/errors.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <system_error>

namespace lobe::tools {

namespace {

// Which image axes span the picture, and whether each runs backwards on screen.
struct Plane {
    int col_axis = 0, row_axis = 1, fixed_axis = 2;
    bool flip_col = false, flip_row = false;
};

// The patient axes (LPS: 0 = x, 1 = y, 2 = z) along the screen's columns and rows and across a view.
struct ViewAxes {
    int col, row, normal;
};

ViewAxes view_axes(SliceAxis axis)
{
    switch (axis) {
    case SliceAxis::Coronal: return {0, 2, 1};
    case SliceAxis::Sagittal: return {1, 2, 0};
    case SliceAxis::Axial: break;
    }
    return {0, 1, 2};
}

// Each screen direction follows the voxel axis nearest its patient axis (core::patient_axis_order),
// so a coronal or sagittal stack is drawn in the same views as an axial one. Screen x runs to the
// patient's left (+x) in axial and coronal views and to posterior (+y) in sagittal ones; screen y
// runs to posterior (+y) in axial views and to inferior (-z) otherwise. A voxel axis pointing the
// other way is read backwards.
Plane plane_of(const core::ImageGeometry& g, SliceAxis axis)
{
    const core::AxisOrder order = core::patient_axis_order(g);
    const ViewAxes v = view_axes(axis);
    const auto at = [](int a) { return static_cast<std::size_t>(a); };
    Plane p;
    p.col_axis = order.from[at(v.col)];
    p.row_axis = order.from[at(v.row)];
    p.fixed_axis = order.from[at(v.normal)];
    p.flip_col = order.flip[at(v.col)];
    p.flip_row = axis == SliceAxis::Axial ? order.flip[1] : !order.flip[2];
    return p;
}

// A label value -> colour table for quick lookup.
struct Palette {
    std::array<int, 256> slot{};
    std::vector<LabelColour> colours;
    explicit Palette(const std::vector<LabelColour>& c) : colours(c.empty() ? default_label_colours() : c)
    {
        slot.fill(-1);
        for (std::size_t i = 0; i < colours.size(); ++i)
            if (colours[i].label >= 0 && colours[i].label < 256)
                slot[static_cast<std::size_t>(colours[i].label)] = static_cast<int>(i);
    }
};

// The index ranges [first, last] along the picture's column and row axes.
struct Window2D {
    int c0 = 0, c1 = 0, r0 = 0, r1 = 0;
    int width() const { return c1 - c0 + 1; }
    int height() const { return r1 - r0 + 1; }
};

template <class T>
cv::Mat extract(const core::Image3D<T>& im, const Plane& p, int index, const Window2D& win, int cv_type)
{
    const int w = win.width(), h = win.height();
    cv::Mat out(h, w, cv_type);
    std::array<int, 3> ijk{};
    ijk[static_cast<std::size_t>(p.fixed_axis)] = index;
    for (int r = 0; r < h; ++r) {
        ijk[static_cast<std::size_t>(p.row_axis)] = p.flip_row ? win.r1 - r : win.r0 + r;
        for (int c = 0; c < w; ++c) {
            ijk[static_cast<std::size_t>(p.col_axis)] = p.flip_col ? win.c1 - c : win.c0 + c;
            const T v = im.at(ijk[0], ijk[1], ijk[2]);
            if (cv_type == CV_32F)
                out.at<float>(r, c) = static_cast<float>(v);
            else
                out.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(v);
        }
    }
    return out;
}

std::string fixed1(double v)
{
    char b[64];
    std::snprintf(b, sizeof b, "%.1f", v);
    return b;
}

} // namespace

int slice_voxel_axis(const core::ImageGeometry& g, SliceAxis axis)
{
    return plane_of(g, axis).fixed_axis;
}

bool axis_runs_backwards(const core::ImageGeometry& g, int voxel_axis)
{
    return core::patient_axis_order(g).inverse().flip[static_cast<std::size_t>(voxel_axis)];
}

int patient_round(const core::ImageGeometry& g, int voxel_axis, double index)
{
    return patient_round(axis_runs_backwards(g, voxel_axis), g.size[static_cast<std::size_t>(voxel_axis)], index);
}

int patient_round(bool backwards, int size, double index)
{
    if (!backwards)
        return static_cast<int>(std::lround(index));
    const double last = size - 1;
    return static_cast<int>(last - double(std::lround(last - index)));
}

int fullest_slice(const std::vector<std::size_t>& counts, bool backwards)
{
    if (counts.empty())
        return 0;
    if (!backwards)
        return static_cast<int>(std::max_element(counts.begin(), counts.end()) - counts.begin());
    return static_cast<int>(counts.rend() - std::max_element(counts.rbegin(), counts.rend())) - 1;
}

LabelViews label_views(const core::LabelImage3D& labels, int fullest_from, int centred_from)
{
    const int ax = slice_voxel_axis(labels, SliceAxis::Axial), co = slice_voxel_axis(labels, SliceAxis::Coronal);
    std::vector<std::size_t> per_slice(static_cast<std::size_t>(labels.size[static_cast<std::size_t>(ax)]), 0);
    double sum = 0, n = 0;
    for (int k = 0; k < labels.size[2]; ++k)
        for (int j = 0; j < labels.size[1]; ++j)
            for (int i = 0; i < labels.size[0]; ++i) {
                const int v = labels.at(i, j, k);
                const int ijk[3] = {i, j, k};
                per_slice[static_cast<std::size_t>(ijk[ax])] += v >= fullest_from;
                if (v >= centred_from) {
                    sum += ijk[co];
                    n += 1;
                }
            }
    LabelViews views;
    views.axial = fullest_slice(per_slice, axis_runs_backwards(labels, ax));
    views.coronal = n > 0 ? patient_round(labels, co, sum / n) : -1;
    return views;
}

SliceAxis view_across(const core::ImageGeometry& g, int voxel_axis)
{
    for (SliceAxis a : {SliceAxis::Axial, SliceAxis::Coronal, SliceAxis::Sagittal})
        if (slice_voxel_axis(g, a) == voxel_axis)
            return a;
    return SliceAxis::Axial; // not reached: the three views cut the three axes
}

const char* slice_axis_name(SliceAxis axis)
{
    switch (axis) {
    case SliceAxis::Axial: return "axial";
    case SliceAxis::Coronal: return "coronal";
    case SliceAxis::Sagittal: return "sagittal";
    }
    return "unknown";
}

const std::vector<LabelColour>& default_label_colours()
{
    static const std::vector<LabelColour> c = {
        {1, {214, 128, 52}, "liver"},
        {2, {170, 70, 255}, "portal vein"},
        {3, {40, 140, 255}, "hepatic veins"},
        {4, {255, 235, 0}, "tumour"},
        {10, {190, 110, 110}, "soft tissue"},
        {11, {240, 220, 140}, "fat"},
        {12, {250, 250, 250}, "bone"},
        {13, {230, 30, 40}, "heart"},
        {14, {0, 200, 110}, "right kidney"},
        {15, {0, 70, 200}, "IVC"},
        {16, {140, 210, 255}, "lungs"},
        {17, {150, 60, 140}, "spleen"},
        {18, {255, 80, 80}, "aorta"},
        {19, {205, 205, 170}, "spine"},
        {20, {255, 140, 0}, "subcostal"},
        {21, {0, 140, 80}, "left kidney"},
        {22, {255, 160, 210}, "stomach"},
        {23, {60, 230, 60}, "gallbladder"},
        {24, {120, 60, 200}, "portal vein (extra)"},
        {25, {255, 110, 120}, "heart blood"},
        {26, {200, 180, 90}, "mediastinum"},
    };
    return c;
}

template <class T>
RgbImage render_slice(const core::Image3D<T>& image, const PictureParams& params, const std::vector<Overlay>& overlays)
{
    const std::string problem = core::geometry_problem(image);
    if (!problem.empty())
        throw core::InvalidInputError("picture: invalid image geometry: " + problem);
    const Plane pl = plane_of(image, params.axis);
    const int depth = image.size[static_cast<std::size_t>(pl.fixed_axis)];
    const int index = params.index < 0 ? depth / 2 : params.index;
    if (index >= depth)
        throw core::InvalidInputError(std::string("picture: ") + slice_axis_name(params.axis) + " slice " +
                                      std::to_string(index) + " is outside the image (0.." +
                                      std::to_string(depth - 1) + ")");
    if (!(params.window > 0))
        throw core::InvalidInputError("picture: the window width must be positive");
    for (const auto& o : overlays)
        if (o.labels && !core::same_grid(*o.labels, image))
            throw core::InvalidInputError("picture: an overlay's label volume is not on the image's grid");

    // The part of the slice inside the region of interest.
    Window2D win{0, image.size[static_cast<std::size_t>(pl.col_axis)] - 1, 0,
                 image.size[static_cast<std::size_t>(pl.row_axis)] - 1};
    if (!(params.roi_lo == params.roi_hi)) {
        double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
        for (int c = 0; c < 8; ++c) {
            const core::Vec3 corner{(c & 1) ? params.roi_hi.x : params.roi_lo.x, (c & 2) ? params.roi_hi.y : params.roi_lo.y,
                                    (c & 4) ? params.roi_hi.z : params.roi_lo.z};
            const core::Vec3 f = image.physical_to_index(corner);
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], f[a]);
                hi[a] = std::max(hi[a], f[a]);
            }
        }
        auto clampi = [](double v, int n) { return static_cast<int>(std::clamp(v, 0.0, double(n - 1))); };
        const int nc = image.size[static_cast<std::size_t>(pl.col_axis)], nr = image.size[static_cast<std::size_t>(pl.row_axis)];
        win = {clampi(std::ceil(lo[pl.col_axis] - 1e-9), nc), clampi(std::floor(hi[pl.col_axis] + 1e-9), nc),
               clampi(std::ceil(lo[pl.row_axis] - 1e-9), nr), clampi(std::floor(hi[pl.row_axis] + 1e-9), nr)};
        if (win.c1 < win.c0 || win.r1 < win.r0 || hi[pl.col_axis] < 0 || hi[pl.row_axis] < 0 ||
            lo[pl.col_axis] > nc - 1 || lo[pl.row_axis] > nr - 1)
            throw core::InvalidInputError("picture: the region of interest does not meet the slice");
    }

    // Square pixels in mm.
    const double s_col = image.spacing[static_cast<std::size_t>(pl.col_axis)];
    const double s_row = image.spacing[static_cast<std::size_t>(pl.row_axis)];
    const int w_in = win.width();
    const int h_in = win.height();
    double px = params.pixel_mm > 0 ? params.pixel_mm : std::min(s_col, s_row);
    const double w_mm = w_in * s_col, h_mm = h_in * s_row;
    const double max_side = std::max(16, params.max_side_px);
    px = std::max(px, std::max(w_mm, h_mm) / max_side);
    const int w = std::max(1, static_cast<int>(std::lround(w_mm / px)));
    const int h = std::max(1, static_cast<int>(std::lround(h_mm / px)));

    cv::Mat grey = extract(image, pl, index, win, CV_32F);
    cv::Mat big;
    cv::resize(grey, big, cv::Size(w, h), 0, 0, cv::INTER_LINEAR);
    const double lo = params.level - params.window / 2;
    cv::Mat g8;
    big.convertTo(g8, CV_8U, 255.0 / params.window, -lo * 255.0 / params.window);
    cv::Mat canvas;
    cv::cvtColor(g8, canvas, cv::COLOR_GRAY2BGR);

    // Overlays: fills first, then contours on top so that lines keep their colour.
    std::vector<LabelColour> legend;
    std::vector<std::pair<cv::Mat, cv::Scalar>> contours_todo;
    std::vector<int> contour_width;
    for (const auto& o : overlays) {
        if (!o.labels)
            continue;
        const Palette pal(o.colours);
        cv::Mat lab = extract(*o.labels, pl, index, win, CV_8U);
        std::array<bool, 256> present{};
        for (int r = 0; r < lab.rows; ++r)
            for (int c = 0; c < lab.cols; ++c)
                present[lab.at<std::uint8_t>(r, c)] = true;
        for (int v = 0; v < 256; ++v) {
            if (!present[static_cast<std::size_t>(v)] || pal.slot[static_cast<std::size_t>(v)] < 0)
                continue;
            const LabelColour& lc = pal.colours[static_cast<std::size_t>(pal.slot[static_cast<std::size_t>(v)])];
            // Upsample the indicator linearly and cut at 1/2: smooth outlines even across thick slices.
            cv::Mat ind = (lab == v);
            cv::Mat indf, up;
            ind.convertTo(indf, CV_32F, 1.0 / 255.0);
            cv::resize(indf, up, cv::Size(w, h), 0, 0, cv::INTER_LINEAR);
            cv::Mat mask = up >= 0.5f;
            if (cv::countNonZero(mask) == 0)
                continue;
            const cv::Scalar bgr(lc.rgb[2], lc.rgb[1], lc.rgb[0]);
            if (o.fill_opacity > 0) {
                cv::Mat solid(canvas.size(), canvas.type(), bgr);
                cv::Mat blended;
                const double a = std::clamp(o.fill_opacity, 0.0, 1.0);
                cv::addWeighted(canvas, 1.0 - a, solid, a, 0.0, blended);
                blended.copyTo(canvas, mask);
            }
            if (o.contour_px > 0) {
                contours_todo.emplace_back(mask, bgr);
                contour_width.push_back(o.contour_px);
            }
            if (o.legend)
                legend.push_back(lc);
        }
    }
    for (std::size_t i = 0; i < contours_todo.size(); ++i) {
        std::vector<std::vector<cv::Point>> cs;
        cv::findContours(contours_todo[i].first, cs, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
        cv::drawContours(canvas, cs, -1, contours_todo[i].second, contour_width[i], cv::LINE_8);
    }

    // Legend panel on the right, caption strip below.
    const int font = cv::FONT_HERSHEY_SIMPLEX;
    const double fs = 0.42;
    const int line_h = 17;
    int legend_w = 0;
    std::sort(legend.begin(), legend.end(), [](const LabelColour& a, const LabelColour& b) { return a.label < b.label; });
    legend.erase(std::unique(legend.begin(), legend.end(),
                             [](const LabelColour& a, const LabelColour& b) { return a.label == b.label; }),
                 legend.end());
    for (const auto& l : legend) {
        int base = 0;
        const cv::Size ts = cv::getTextSize(std::to_string(l.label) + " " + l.name, font, fs, 1, &base);
        legend_w = std::max(legend_w, ts.width + 34);
    }
    std::string caption = params.caption;
    if (params.auto_caption) {
        std::array<int, 3> ijk{0, 0, 0};
        ijk[static_cast<std::size_t>(pl.fixed_axis)] = index;
        const core::Vec3 pos = image.index_to_physical(ijk[0], ijk[1], ijk[2]);
        static const char* kIdx[3] = {"i", "j", "k"};
        static const char* kCoord[3] = {"x", "y", "z"};
        const int comp = params.axis == SliceAxis::Axial ? 2 : (params.axis == SliceAxis::Coronal ? 1 : 0);
        std::string a = std::string(slice_axis_name(params.axis)) + " " + kIdx[pl.fixed_axis] + "=" +
                        std::to_string(index) + " (" + kCoord[comp] + "=" + fixed1(pos[comp]) + " mm)  W" +
                        std::to_string(static_cast<long>(std::lround(params.window))) + "/L" +
                        std::to_string(static_cast<long>(std::lround(params.level)));
        caption = caption.empty() ? a : caption + "  |  " + a;
    }
    const int legend_h = legend.empty() ? 0 : static_cast<int>(legend.size()) * line_h + 10;
    const int caption_h = caption.empty() ? 0 : 22;
    const int out_w = w + (legend.empty() ? 0 : legend_w + 8);
    const int out_h = std::max(h, legend_h) + caption_h;
    cv::Mat out(out_h, out_w, CV_8UC3, cv::Scalar(24, 24, 24));
    canvas.copyTo(out(cv::Rect(0, 0, w, h)));
    for (std::size_t i = 0; i < legend.size(); ++i) {
        const int y = 8 + static_cast<int>(i) * line_h;
        const cv::Scalar bgr(legend[i].rgb[2], legend[i].rgb[1], legend[i].rgb[0]);
        cv::rectangle(out, cv::Rect(w + 8, y, 20, line_h - 5), bgr, cv::FILLED);
        cv::putText(out, std::to_string(legend[i].label) + " " + legend[i].name, cv::Point(w + 34, y + line_h - 6),
                    font, fs, cv::Scalar(235, 235, 235), 1, cv::LINE_AA);
    }
    if (!caption.empty()) {
        double cs = fs;
        int base = 0;
        cv::Size ts = cv::getTextSize(caption, font, cs, 1, &base);
        if (ts.width > out_w - 8)
            cs *= double(out_w - 8) / ts.width;
        cv::putText(out, caption, cv::Point(4, out_h - 7), font, cs, cv::Scalar(235, 235, 235), 1, cv::LINE_AA);
    }

    RgbImage res;
    res.width = out.cols;
    res.height = out.rows;
    res.rgb.resize(static_cast<std::size_t>(out.cols) * static_cast<std::size_t>(out.rows) * 3);
    cv::Mat rgb(out.rows, out.cols, CV_8UC3, res.rgb.data());
    cv::cvtColor(out, rgb, cv::COLOR_BGR2RGB);
    return res;
}

RgbImage render_slice(const core::AnyImage& image, const PictureParams& params, const std::vector<Overlay>& overlays)
{
    return std::visit([&](const auto& im) { return render_slice(im, params, overlays); }, image);
}

void write_png(const std::filesystem::path& path, const RgbImage& picture)
{
    if (picture.width <= 0 || picture.height <= 0 ||
        picture.rgb.size() != static_cast<std::size_t>(picture.width) * static_cast<std::size_t>(picture.height) * 3)
        throw core::InvalidInputError(path.string() + ": cannot write an empty or inconsistent picture");
    cv::Mat rgb(picture.height, picture.width, CV_8UC3, const_cast<std::uint8_t*>(picture.rgb.data()));
    cv::Mat bgr;
    cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
    std::vector<std::uint8_t> bytes;
    if (!cv::imencode(".png", bgr, bytes, {cv::IMWRITE_PNG_COMPRESSION, 9}))
        throw core::IoError(path.string() + ": PNG encoding failed");

    write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

template RgbImage render_slice(const core::Image3D<std::uint8_t>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<std::int8_t>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<std::int16_t>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<std::uint16_t>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<std::int32_t>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<std::uint32_t>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<float>&, const PictureParams&, const std::vector<Overlay>&);
template RgbImage render_slice(const core::Image3D<double>&, const PictureParams&, const std::vector<Overlay>&);

} // namespace lobe::tools
