// Mesh and force pictures for lsim --png.
#include "lsim/render.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>

namespace lobe::lsim {
namespace {

constexpr int kWidth = 800, kHeight = 600;

// Orthographic camera: azimuth 30 degrees from the front (-y in LPS), elevation 20 degrees.
struct Camera {
    core::Vec3 right, up, towards; // towards: from the scene to the viewer
    double scale = 1, cx = 0, cy = 0;

    Camera()
    {
        const double az = 30 * M_PI / 180, el = 20 * M_PI / 180;
        towards = {-std::sin(az) * std::cos(el), -std::cos(az) * std::cos(el), std::sin(el)};
        right = normalized(cross(core::Vec3{0, 0, 1}, towards));
        up = cross(towards, right);
    }
    cv::Point2d project(const core::Vec3& p) const
    {
        return {kWidth / 2.0 + scale * (dot(p, right) - cx), kHeight / 2.0 - scale * (dot(p, up) - cy)};
    }
};

tools::RgbImage to_rgb(const cv::Mat& bgr)
{
    tools::RgbImage out;
    out.width = bgr.cols;
    out.height = bgr.rows;
    out.rgb.resize(std::size_t(3) * out.width * out.height);
    for (int y = 0; y < bgr.rows; ++y)
        for (int x = 0; x < bgr.cols; ++x) {
            const auto& c = bgr.at<cv::Vec3b>(y, x);
            const std::size_t i = 3 * (std::size_t(y) * out.width + x);
            out.rgb[i] = c[2];
            out.rgb[i + 1] = c[1];
            out.rgb[i + 2] = c[0];
        }
    return out;
}

std::string g3(double v, const char* unit)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.3g %s", v, unit);
    return buf;
}

} // namespace

tools::RgbImage render_mesh(const Snapshot& shot, const std::vector<core::Vec3>& framing, const std::string& caption)
{
    Camera cam;
    // Frame the rest mesh with a margin for the deformation.
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const auto& v : framing) {
        x0 = std::min(x0, dot(v, cam.right));
        x1 = std::max(x1, dot(v, cam.right));
        y0 = std::min(y0, dot(v, cam.up));
        y1 = std::max(y1, dot(v, cam.up));
    }
    cam.scale = 0.7 * std::min(kWidth / std::max(x1 - x0, 1e-9), (kHeight - 40) / std::max(y1 - y0, 1e-9));
    cam.cx = (x0 + x1) / 2;
    cam.cy = (y0 + y1) / 2;
    cv::Mat img(kHeight, kWidth, CV_8UC3, cv::Scalar(255, 255, 255));

    const auto& pos = shot.positions;
    const auto& faces = shot.faces;
    std::vector<char> cut(faces.size(), 0);
    {
        auto key = [](std::array<std::int32_t, 3> f) {
            std::sort(f.begin(), f.end());
            return f;
        };
        std::vector<std::array<std::int32_t, 3>> keys;
        for (const auto& f : shot.cut_faces)
            keys.push_back(key(f));
        std::sort(keys.begin(), keys.end());
        for (std::size_t f = 0; f < faces.size(); ++f)
            cut[f] = std::binary_search(keys.begin(), keys.end(), key(faces[f]));
    }
    std::vector<std::size_t> order(faces.size());
    std::iota(order.begin(), order.end(), 0);
    std::vector<double> depth(faces.size());
    for (std::size_t f = 0; f < faces.size(); ++f)
        depth[f] = dot(pos[std::size_t(faces[f][0])] + pos[std::size_t(faces[f][1])] + pos[std::size_t(faces[f][2])], cam.towards);
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return depth[a] < depth[b]; });
    const auto& palette = tools::default_label_colours();
    const core::Vec3 light = normalized(cam.towards + cam.up * 0.5 + cam.right * 0.3);
    for (const std::size_t f : order) {
        const auto& q = faces[f];
        const core::Vec3 a = pos[std::size_t(q[0])], b = pos[std::size_t(q[1])], c = pos[std::size_t(q[2])];
        const core::Vec3 n = normalized(cross(b - a, c - a));
        if (dot(n, cam.towards) <= 0)
            continue; // facing away
        std::array<std::uint8_t, 3> rgb{200, 120, 90};
        for (const auto& col : palette)
            if (col.label == shot.labels[f])
                rgb = col.rgb;
        if (cut[f])
            rgb = {200, 60, 60}; // the raw tissue a cut has exposed
        const double shade = 0.35 + 0.65 * std::max(0.0, dot(n, light));
        cv::Point pts[3];
        for (int k = 0; k < 3; ++k) {
            const auto p = cam.project(pos[std::size_t(q[std::size_t(k)])]);
            pts[k] = {int(std::lround(p.x)), int(std::lround(p.y))};
        }
        cv::fillConvexPoly(img, pts, 3, cv::Scalar(rgb[2] * shade, rgb[1] * shade, rgb[0] * shade), cv::LINE_AA);
        cv::polylines(img, std::vector<std::vector<cv::Point>>{{pts[0], pts[1], pts[2]}}, true, cv::Scalar(60, 60, 60), 1,
                      cv::LINE_AA);
    }
    // The cut line: where a cut's faces meet the rest of the surface, drawn in red even while
    // the lips are closed.
    {
        std::map<std::pair<std::int32_t, std::int32_t>, int> edges; // +1 per cut face, +2 per other
        for (std::size_t f = 0; f < faces.size(); ++f)
            for (int k = 0; k < 3; ++k) {
                const auto a = faces[f][std::size_t(k)], b = faces[f][std::size_t((k + 1) % 3)];
                edges[{std::min(a, b), std::max(a, b)}] |= cut[f] ? 1 : 2;
            }
        for (const auto& [e, kind] : edges) {
            if (kind != 3)
                continue;
            const auto pa = cam.project(pos[std::size_t(e.first)]), pb = cam.project(pos[std::size_t(e.second)]);
            cv::line(img, {int(std::lround(pa.x)), int(std::lround(pa.y))}, {int(std::lround(pb.x)), int(std::lround(pb.y))},
                     cv::Scalar(40, 40, 220), 2, cv::LINE_AA);
        }
    }
    for (const auto& s : shot.spheres) {
        const auto c = cam.project(s.centre_mm);
        const cv::Point centre{int(std::lround(c.x)), int(std::lround(c.y))};
        const int r = int(std::lround(cam.scale * s.radius_mm));
        if (s.forceps) {
            // Two jaws: closed, they meet on the tissue; open, they stand apart.
            const int gap = s.closed ? 0 : r / 2;
            for (int side : {-1, 1}) {
                const cv::Point tip{centre.x + side * gap, centre.y};
                const cv::Point heel{centre.x + side * (gap + r / 3), centre.y - 3 * r};
                cv::line(img, tip, heel, cv::Scalar(90, 90, 90), std::max(2, r / 4), cv::LINE_AA);
            }
            cv::circle(img, centre, r, cv::Scalar(40, 40, 40), 1, cv::LINE_AA);
            continue;
        }
        cv::Mat overlay = img.clone();
        cv::circle(overlay, centre, r, cv::Scalar(150, 150, 150), cv::FILLED, cv::LINE_AA);
        cv::addWeighted(overlay, 0.6, img, 0.4, 0, img);
        cv::circle(img, centre, r, cv::Scalar(40, 40, 40), 1, cv::LINE_AA);
    }
    for (const auto& [a, b] : shot.blades) {
        const auto pa = cam.project(a), pb = cam.project(b);
        cv::line(img, {int(std::lround(pa.x)), int(std::lround(pa.y))}, {int(std::lround(pb.x)), int(std::lround(pb.y))},
                 cv::Scalar(30, 30, 30), 3, cv::LINE_AA);
    }
    cv::putText(img, caption, {10, kHeight - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    return to_rgb(img);
}

tools::RgbImage plot_force(const std::vector<io::SimulationStep>& steps, const std::string& caption)
{
    const int w = 800, h = 400, left = 70, right = 20, top = 20, bottom = 60;
    cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
    double t1 = 1e-9, fmax = 1e-9, fmin = 0;
    for (const auto& s : steps) {
        t1 = std::max(t1, s.time);
        fmax = std::max({fmax, norm(s.force), s.force.x, s.force.y, s.force.z});
        fmin = std::min({fmin, s.force.x, s.force.y, s.force.z});
    }
    auto px = [&](double t, double f) {
        return cv::Point(int(left + (w - left - right) * t / t1), int(h - bottom - (h - top - bottom) * (f - fmin) / (fmax - fmin)));
    };
    cv::rectangle(img, {left, top}, {w - right, h - bottom}, cv::Scalar(0, 0, 0));
    cv::line(img, px(0, 0), px(t1, 0), cv::Scalar(180, 180, 180));
    const cv::Scalar colours[4] = {cv::Scalar(0, 0, 0), cv::Scalar(60, 60, 220), cv::Scalar(60, 160, 60), cv::Scalar(220, 90, 30)};
    const char* names[4] = {"|F|", "Fx", "Fy", "Fz"};
    for (int c = 0; c < 4; ++c) {
        std::vector<cv::Point> line;
        for (const auto& s : steps)
            line.push_back(px(s.time, c == 0 ? norm(s.force) : s.force[c - 1]));
        if (line.size() > 1)
            cv::polylines(img, std::vector<std::vector<cv::Point>>{line}, false, colours[c], 1, cv::LINE_AA);
        cv::putText(img, names[c], {left + 10 + 50 * c, top + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.5, colours[c], 1, cv::LINE_AA);
    }
    cv::putText(img, g3(fmax, "N"), {5, top + 10}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::putText(img, g3(fmin, "N"), {5, h - bottom}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::putText(img, g3(t1, "s"), {w - right - 60, h - bottom + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
    cv::putText(img, "0 s", {left - 5, h - bottom + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::putText(img, caption, {10, h - 15}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    return to_rgb(img);
}

} // namespace lobe::lsim
