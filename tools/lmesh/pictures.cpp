#include "lmesh/pictures.h"

#include "common/picture.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lobe::lmesh {

namespace fs = std::filesystem;
using core::Vec3;

namespace {

// Band colours (RGB) of the thesis's quality bands: worst to best.
cv::Scalar band_colour(double q)
{
    if (q < 0.3)
        return {214, 39, 40};
    if (q < 0.5)
        return {255, 127, 14};
    if (q < 0.7)
        return {230, 200, 40};
    return {44, 160, 44};
}

cv::Scalar tissue_colour(int label)
{
    for (const auto& c : tools::default_label_colours())
        if (c.label == label)
            return {double(c.rgb[0]), double(c.rgb[1]), double(c.rgb[2])};
    return {150, 150, 150};
}

tools::RgbImage to_rgb(const cv::Mat& m)
{
    tools::RgbImage out;
    out.width = m.cols;
    out.height = m.rows;
    out.rgb.assign(m.data, m.data + m.total() * 3);
    return out;
}

struct View {
    const char* name;
    int normal;    // axis of the plane normal (x=0, y=1, z=2)
    int u, v;      // axes drawn to the right and downward
    double su, sv; // sign applied to them (radiological layout for LPS)
};

// Axial: patient's right on the left, anterior at the top; coronal and sagittal: superior up.
constexpr View kViews[] = {{"axial", 2, 0, 1, 1, 1}, {"coronal", 1, 0, 2, 1, -1}, {"sagittal", 0, 1, 2, 1, -1}};

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.5, cv::Scalar colour = {0, 0, 0})
{
    cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

// The mesh cut by the plane of `view` through `centre`: each cut tet drawn as its polygon.
cv::Mat cut_picture(const core::TetMesh& m, const std::vector<double>& quality, const View& view, const Vec3& centre,
                    bool by_quality, const std::vector<std::pair<int, std::string>>& names)
{
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const auto& p : m.vertices)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    const double eu = hi[view.u] - lo[view.u], ev = hi[view.v] - lo[view.v];
    const double mm_per_px = std::max({eu, ev, 1e-6}) / 800.0;
    const int margin = 20, legend = 30;
    const int w = static_cast<int>(eu / mm_per_px) + 2 * margin, h = static_cast<int>(ev / mm_per_px) + 2 * margin + legend;
    cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
    auto px = [&](const Vec3& p) {
        const double u = view.su > 0 ? p[view.u] - lo[view.u] : hi[view.u] - p[view.u];
        const double v = view.sv > 0 ? p[view.v] - lo[view.v] : hi[view.v] - p[view.v];
        return cv::Point2d(margin + u / mm_per_px, margin + v / mm_per_px);
    };
    const double c = centre[view.normal];
    int cut = 0;
    for (std::size_t t = 0; t < m.tets.size(); ++t) {
        const auto& q = m.tets[t];
        double d[4];
        for (int i = 0; i < 4; ++i)
            d[i] = m.vertices[static_cast<std::size_t>(q[static_cast<std::size_t>(i)])][view.normal] - c;
        std::vector<cv::Point2d> pts;
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j)
                if ((d[i] < 0) != (d[j] < 0)) {
                    const Vec3& a = m.vertices[static_cast<std::size_t>(q[static_cast<std::size_t>(i)])];
                    const Vec3& b = m.vertices[static_cast<std::size_t>(q[static_cast<std::size_t>(j)])];
                    pts.push_back(px(a + (b - a) * (d[i] / (d[i] - d[j]))));
                }
        if (pts.size() < 3)
            continue;
        ++cut;
        cv::Point2d mid(0, 0);
        for (const auto& p : pts)
            mid += p / double(pts.size());
        std::sort(pts.begin(), pts.end(), [&](const cv::Point2d& a, const cv::Point2d& b) {
            return std::atan2(a.y - mid.y, a.x - mid.x) < std::atan2(b.y - mid.y, b.x - mid.x);
        });
        std::vector<cv::Point> poly;
        for (const auto& p : pts)
            poly.emplace_back(static_cast<int>(std::lround(p.x * 4)), static_cast<int>(std::lround(p.y * 4)));
        const cv::Scalar fill = by_quality ? band_colour(quality[t]) : tissue_colour(m.tet_labels[t]);
        cv::fillConvexPoly(img, poly, fill, cv::LINE_AA, 2);
        cv::polylines(img, std::vector<std::vector<cv::Point>>{poly}, true, cv::Scalar(60, 60, 60), 1, cv::LINE_AA, 2);
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s cut at %.1f mm: %d tets", view.name, c, cut);
    int x = margin;
    const int y = h - 10;
    text(img, buf, {x, y});
    x += 260;
    if (by_quality) {
        const std::pair<double, const char*> bands[] = {{0.1, "<0.3"}, {0.4, "0.3-0.5"}, {0.6, "0.5-0.7"}, {0.8, ">=0.7"}};
        for (const auto& [q, label] : bands) {
            cv::rectangle(img, cv::Rect(x, y - 11, 12, 12), band_colour(q), cv::FILLED);
            text(img, label, {x + 16, y});
            x += 90;
        }
    } else {
        for (const auto& [label, name] : names) {
            cv::rectangle(img, cv::Rect(x, y - 11, 12, 12), tissue_colour(label), cv::FILLED);
            text(img, name, {x + 16, y});
            x += 20 + 9 * static_cast<int>(name.size());
        }
    }
    return img;
}

cv::Mat histogram_picture(const mesh::MeshQuality& q, const std::vector<std::pair<int, std::string>>& names)
{
    std::vector<const mesh::TissueQuality*> panels{&q.all};
    for (const auto& t : q.tissues)
        panels.push_back(&t);
    const int pw = 640, ph = 170, left = 60, bottom = 30;
    cv::Mat img(ph * static_cast<int>(panels.size()), pw, CV_8UC3, cv::Scalar(255, 255, 255));
    const int measure = static_cast<int>(mesh::Measure::Combined);
    for (std::size_t p = 0; p < panels.size(); ++p) {
        const auto& s = panels[p]->measures[static_cast<std::size_t>(measure)];
        const int y0 = static_cast<int>(p) * ph;
        std::string title = "all tissues";
        for (const auto& [label, name] : names)
            if (label == panels[p]->label)
                title = name;
        const int bins = static_cast<int>(s.histogram.size());
        std::int64_t top = 1;
        for (auto c : s.histogram)
            top = std::max(top, c);
        const int plot_h = ph - bottom - 25, plot_w = pw - left - 20;
        for (int b = 0; b < bins; ++b) {
            const double frac = double(s.histogram[static_cast<std::size_t>(b)]) / double(top);
            const int bh = static_cast<int>(frac * plot_h);
            const int x0 = left + b * plot_w / bins, x1 = left + (b + 1) * plot_w / bins - 1;
            cv::rectangle(img, cv::Rect(x0, y0 + 20 + plot_h - bh, x1 - x0, bh), band_colour((b + 0.5) / bins), cv::FILLED);
        }
        cv::line(img, {left, y0 + 20 + plot_h}, {left + plot_w, y0 + 20 + plot_h}, {0, 0, 0});
        for (double t : {0.0, 0.3, 0.5, 0.7, 1.0}) {
            const int x = left + static_cast<int>(t * plot_w);
            cv::line(img, {x, y0 + 20 + plot_h}, {x, y0 + 25 + plot_h}, {0, 0, 0});
            char buf[16];
            std::snprintf(buf, sizeof buf, "%.1f", t);
            text(img, buf, {x - 10, y0 + 40 + plot_h}, 0.4);
        }
        char buf[200];
        std::snprintf(buf, sizeof buf, "%s: combined quality of %lld tets (min %.3f, mean %.3f); max bin %lld", title.c_str(),
                      static_cast<long long>(s.count), s.min, s.mean, static_cast<long long>(top));
        text(img, buf, {10, y0 + 15}, 0.45);
    }
    return img;
}

} // namespace

std::vector<fs::path> write_mesh_pictures(const fs::path& dir, const core::TetMesh& mesh, const mesh::MeshQuality& quality,
                                          const Vec3& centre, const std::vector<std::pair<int, std::string>>& names)
{
    fs::create_directories(dir);
    std::vector<fs::path> out;
    const auto& comb = quality.per_tet[static_cast<std::size_t>(mesh::Measure::Combined)];
    for (const auto& view : kViews)
        for (bool by_quality : {false, true}) {
            const fs::path path = dir / (std::string("cut-") + view.name + (by_quality ? "-quality" : "-tissue") + ".png");
            tools::write_png(path, to_rgb(cut_picture(mesh, comb, view, centre, by_quality, names)));
            out.push_back(path);
        }
    const fs::path hist = dir / "quality-histogram.png";
    tools::write_png(hist, to_rgb(histogram_picture(quality, names)));
    out.push_back(hist);
    return out;
}

} // namespace lobe::lmesh
