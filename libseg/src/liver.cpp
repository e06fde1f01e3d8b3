// The liver pipeline's driver: slice-by-slice CDSG propagation (docs/algorithms/liver.md).
#include "lobe/seg/liver.h"

#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/edge_map.h"

#include "detail/volume.h"

#include <omp.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <future>
#include <initializer_list>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>
#include <utility>

namespace lobe::seg {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

double pixel_area_mm2(const core::ImageGeometry& g)
{
    return g.spacing[0] * g.spacing[1];
}

std::size_t count(const core::LabelImage3D& m)
{
    return static_cast<std::size_t>(std::count_if(m.data.begin(), m.data.end(), [](std::uint8_t v) { return v != 0; }));
}

//! The mask `m` (any one-slice geometry of the same size) re-placed on slice geometry `g`.
core::LabelImage3D on_grid(const core::LabelImage3D& m, const core::ImageGeometry& g)
{
    core::LabelImage3D out(g, 0);
    out.data = m.data;
    return out;
}

//! An axis-aligned window [i0, i0 + ni) x [j0, j0 + nj) of a one-slice grid.
struct Window {
    int i0 = 0, j0 = 0, ni = 0, nj = 0;
};

//! The window around the non-zero voxels of `m`, widened by margin_mm, clipped to the grid.
Window window_around(const core::LabelImage3D& m, double margin_mm)
{
    const detail::Box b = detail::bounding_box(m);
    const int i0 = b.lo[0], i1 = b.hi[0], j0 = b.lo[1], j1 = b.hi[1];
    const int mi = static_cast<int>(std::ceil(margin_mm / m.spacing[0]));
    const int mj = static_cast<int>(std::ceil(margin_mm / m.spacing[1]));
    Window w;
    w.i0 = std::max(0, i0 - mi);
    w.j0 = std::max(0, j0 - mj);
    w.ni = std::min(m.size[0] - 1, i1 + mi) - w.i0 + 1;
    w.nj = std::min(m.size[1] - 1, j1 + mj) - w.j0 + 1;
    return w;
}

//! The window as a box of the one-slice grid.
detail::Box box_of(const Window& w)
{
    return {{w.i0, w.j0, 0}, {w.i0 + w.ni - 1, w.j0 + w.nj - 1, 0}};
}

//! True if the window's mask `m_w` reaches an edge of window `w` that is not an edge of the
//! slice grid `g` (the contour was stopped by the window).
bool reaches_inner_edge(const core::LabelImage3D& m_w, const Window& w, const core::ImageGeometry& g)
{
    if (count(m_w) == 0)
        return false;
    const detail::Box b = detail::bounding_box(m_w);
    return (b.lo[0] == 0 && w.i0 > 0) || (b.lo[1] == 0 && w.j0 > 0) ||
           (b.hi[0] == w.ni - 1 && w.i0 + w.ni < g.size[0]) || (b.hi[1] == w.nj - 1 && w.j0 + w.nj < g.size[1]);
}

template <class T>
core::Image3D<T> crop(const core::Image3D<T>& img, const Window& w)
{
    return detail::crop(img, box_of(w));
}

template <class T>
void paste(const core::Image3D<T>& part, const Window& w, core::Image3D<T>& into)
{
    detail::paste(into, part, box_of(w));
}

//! Voxels within r_mm of `m`: a Euclidean dilation in mm.
core::LabelImage3D grow(const core::LabelImage3D& m, double r_mm)
{
    const core::ImageF d = euclidean_distance(m);
    core::LabelImage3D out(m.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        out.data[i] = double(d.data[i]) <= r_mm ? 1 : 0;
    return out;
}

//! Voxels of `m` farther than r_mm from its outside: a Euclidean erosion in mm.
core::LabelImage3D shrink(const core::LabelImage3D& m, double r_mm)
{
    core::LabelImage3D outside(m.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        outside.data[i] = m.data[i] ? 0 : 1;
    const core::ImageF d = euclidean_distance(outside);
    core::LabelImage3D out(m.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        out.data[i] = m.data[i] && double(d.data[i]) > r_mm ? 1 : 0;
    return out;
}

//! What a slice's separate pieces carry to the next slice: per pixel of its mask, the area its
//! piece had and the largest piece's area when that piece split off (0: the largest piece, or a
//! piece without a lineage).
struct PieceLineage {
    std::vector<float> birth_area, birth_main;
};

//! Drops from the one-slice mask `m` every separate 8-connected piece (not its largest) that
//! touches none of the previous slice's largest piece and either has more than `limit` times the
//! pixels of the previous slice's pieces it overlaps, or has grown, since it split off, more than
//! `lineage_limit` times as much as the largest piece (both as a ratio of areas). Drops only when
//! `past_widest`; the lineage is carried on every slice. `before` is the previous slice's lineage
//! (empty: none), `after` receives this slice's. Returns the pixels dropped.
std::size_t drop_growing_pieces(core::LabelImage3D& m, const core::LabelImage3D& previous, const PieceLineage& before,
                                PieceLineage& after, bool past_widest, double limit, double lineage_limit)
{
    after.birth_area.assign(m.data.size(), 0.0f);
    after.birth_main.assign(m.data.size(), 0.0f);
    cv::Mat cur(m.size[1], m.size[0], CV_8U, m.data.data());
    cv::Mat prev(previous.size[1], previous.size[0], CV_8U, const_cast<std::uint8_t*>(previous.data.data()));
    cv::Mat lc, lp, sc, sp, centroids;
    const int nc = cv::connectedComponentsWithStats(cur, lc, sc, centroids, 8, CV_32S);
    if (nc <= 2)
        return 0; // one piece (or none): nothing separate
    const int np = cv::connectedComponentsWithStats(prev, lp, sp, centroids, 8, CV_32S);
    const auto largest = [](const cv::Mat& stats, int n) {
        int best = 0;
        for (int l = 1; l < n; ++l)
            if (!best || stats.at<int>(l, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA))
                best = l;
        return best;
    };
    const int cur_main = largest(sc, nc), prev_main = largest(sp, np);
    const auto area = [](const cv::Mat& stats, int l) { return double(stats.at<int>(l, cv::CC_STAT_AREA)); };
    // The previous pieces' lineage (read at any of their pixels: a piece's pixels all hold the same).
    std::vector<double> prev_birth_area(static_cast<std::size_t>(np), 0.0), prev_birth_main(static_cast<std::size_t>(np), 0.0);
    const bool has_before = before.birth_area.size() == m.data.size();
    std::vector<std::vector<char>> overlap(static_cast<std::size_t>(nc),
                                           std::vector<char>(static_cast<std::size_t>(np), 0));
    for (int j = 0; j < lc.rows; ++j)
        for (int i = 0; i < lc.cols; ++i) {
            const int a = lc.at<int>(j, i), b = lp.at<int>(j, i);
            if (a && b)
                overlap[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)] = 1;
            if (b && has_before) {
                const std::size_t idx = static_cast<std::size_t>(j) * static_cast<std::size_t>(lc.cols) + static_cast<std::size_t>(i);
                prev_birth_area[static_cast<std::size_t>(b)] = before.birth_area[idx];
                prev_birth_main[static_cast<std::size_t>(b)] = before.birth_main[idx];
            }
        }
    std::vector<char> drop(static_cast<std::size_t>(nc), 0);
    std::vector<double> birth_area(static_cast<std::size_t>(nc), 0.0), birth_main(static_cast<std::size_t>(nc), 0.0);
    for (int l = 1; l < nc; ++l) {
        if (l == cur_main)
            continue;
        const auto& o = overlap[static_cast<std::size_t>(l)];
        // A piece just split off the main one starts its lineage here.
        birth_area[static_cast<std::size_t>(l)] = area(sc, l);
        birth_main[static_cast<std::size_t>(l)] = area(sc, cur_main);
        if (prev_main > 0 && o[static_cast<std::size_t>(prev_main)])
            continue; // split off the main piece on this slice: no predecessor of its own yet
        double pred = 0, pred_birth = 0, pred_main = 0;
        bool lineage = true;
        for (int b = 1; b < np; ++b)
            if (o[static_cast<std::size_t>(b)]) {
                pred += area(sp, b);
                pred_birth += prev_birth_area[static_cast<std::size_t>(b)];
                pred_main = std::max(pred_main, prev_birth_main[static_cast<std::size_t>(b)]);
                lineage = lineage && prev_birth_area[static_cast<std::size_t>(b)] > 0;
            }
        if (lineage && pred > 0) {
            birth_area[static_cast<std::size_t>(l)] = pred_birth;
            birth_main[static_cast<std::size_t>(l)] = pred_main;
        }
        // The liver shrinks past its widest slice, all its pieces alike; a neighbour carried
        // along beside it keeps its own size (the kidney under the tip, at thin slices too,
        // where it grows by a few per cent a slice).
        const double own = area(sc, l) / birth_area[static_cast<std::size_t>(l)];
        const double main = area(sc, cur_main) / birth_main[static_cast<std::size_t>(l)];
        if (past_widest && (area(sc, l) > limit * pred || own > lineage_limit * main))
            drop[static_cast<std::size_t>(l)] = 1;
    }
    std::size_t dropped = 0;
    for (int j = 0; j < lc.rows; ++j)
        for (int i = 0; i < lc.cols; ++i) {
            const auto l = static_cast<std::size_t>(lc.at<int>(j, i));
            if (!l)
                continue;
            if (drop[l]) {
                cur.at<uchar>(j, i) = 0;
                ++dropped;
            } else if (static_cast<int>(l) != cur_main) {
                const std::size_t idx = static_cast<std::size_t>(j) * static_cast<std::size_t>(lc.cols) + static_cast<std::size_t>(i);
                after.birth_area[idx] = static_cast<float>(birth_area[l]);
                after.birth_main[idx] = static_cast<float>(birth_main[l]);
            }
        }
    return dropped;
}

//! Keeps the 8-connected pieces of a one-slice mask that have at least min_pixels and either
//! have at least `fraction` of the largest piece's pixels or lie along `rim` for at least
//! `rim_fraction` of their border. A piece enclosed by edges and touching the rim only briefly is
//! an organ that took the liver's place (the heart rising into the dome touches the liver's
//! surface at one notch); a lobe cut off by a vessel or fissure lies along the surface. Returns
//! the dropped pieces of at least min_pixels (what the snake must not enter on this slice).
core::LabelImage3D keep_liver_pieces(core::LabelImage3D& m, const core::LabelImage3D& rim, int min_pixels, double fraction,
                                     double rim_fraction)
{
    cv::Mat bin(m.size[1], m.size[0], CV_8U, m.data.data());
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(bin, labels, stats, centroids, 8, CV_32S);
    const auto at = [&](int i, int j) { return static_cast<std::size_t>(labels.at<int>(j, i)); };
    std::vector<int> on_rim(static_cast<std::size_t>(n), 0), border(static_cast<std::size_t>(n), 0);
    for (int j = 0; j < m.size[1]; ++j)
        for (int i = 0; i < m.size[0]; ++i) {
            const std::size_t c = at(i, j);
            if (c == 0)
                continue;
            const bool edge = i == 0 || j == 0 || i + 1 == m.size[0] || j + 1 == m.size[1] || at(i - 1, j) != c ||
                              at(i + 1, j) != c || at(i, j - 1) != c || at(i, j + 1) != c;
            if (edge) {
                ++border[c];
                on_rim[c] += rim.at(i, j, 0) ? 1 : 0;
            }
        }
    int largest = 0;
    for (int c = 1; c < n; ++c)
        largest = std::max(largest, stats.at<int>(c, cv::CC_STAT_AREA));
    std::vector<std::uint8_t> keep(static_cast<std::size_t>(n), 0), drop(static_cast<std::size_t>(n), 0);
    for (int c = 1; c < n; ++c) {
        const auto u = static_cast<std::size_t>(c);
        const int area = stats.at<int>(c, cv::CC_STAT_AREA);
        const bool along_rim = on_rim[u] >= rim_fraction * border[u] && on_rim[u] > 0;
        keep[u] = area >= min_pixels && (along_rim || area >= fraction * largest);
        drop[u] = area >= min_pixels && !keep[u];
    }
    core::LabelImage3D dropped(m.geometry(), 0);
    for (int j = 0; j < m.size[1]; ++j)
        for (int i = 0; i < m.size[0]; ++i) {
            const std::size_t idx = static_cast<std::size_t>(i) + static_cast<std::size_t>(m.size[0]) * static_cast<std::size_t>(j);
            m.data[idx] = m.data[idx] && keep[at(i, j)] ? 1 : 0;
            dropped.data[idx] = drop[at(i, j)];
        }
    return dropped;
}

//! `m` with its holes filled: what the border cannot reach through the background (4-connected).
core::LabelImage3D filled(core::LabelImage3D m)
{
    cv::Mat padded(m.size[1] + 2, m.size[0] + 2, CV_8U, cv::Scalar(0));
    cv::Mat(m.size[1], m.size[0], CV_8U, m.data.data()).copyTo(padded(cv::Rect(1, 1, m.size[0], m.size[1])));
    cv::floodFill(padded, cv::Point(0, 0), cv::Scalar(2), nullptr, cv::Scalar(0), cv::Scalar(0), 4);
    for (int j = 0; j < m.size[1]; ++j)
        for (int i = 0; i < m.size[0]; ++i)
            m.at(i, j, 0) = padded.at<std::uint8_t>(j + 1, i + 1) != 2 ? 1 : 0;
    return m;
}

//! The grey levels on the midline of the narrowest gap between `piece` and the kept pieces of `m`
//! (`to_kept`: the distance to them): the pixels in neither (not in `m` or `dropped`), inside
//! `inside` or brighter than `bright` in `smoothed`, whose larger distance to the two is at most
//! two pixels more than the smallest such distance r; none if r exceeds limit_mm. (A vein that
//! reached the liver's surface on the previous slice lay in a notch of its contour, outside
//! `inside`; the gap across it is still a gap within the liver.)
std::vector<float> gap_midline(const cv::Mat& piece, const core::ImageF& to_kept, const core::LabelImage3D& inside,
                               const core::LabelImage3D& m, const core::LabelImage3D& dropped,
                               const core::ImageF& smoothed, double limit_mm, double bright)
{
    core::LabelImage3D piece_mask(m.geometry(), 0);
    for (std::size_t i = 0; i < piece_mask.data.size(); ++i)
        piece_mask.data[i] = piece.data[i] ? 1 : 0;
    const core::ImageF dp = euclidean_distance(piece_mask);
    const auto& dk = to_kept.data;
    const auto candidate = [&](std::size_t i) {
        return (inside.data[i] || double(smoothed.data[i]) > bright) && !m.data[i] && !dropped.data[i];
    };
    float r = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < dp.data.size(); ++i)
        if (candidate(i))
            r = std::min(r, std::max(dp.data[i], dk[i]));
    std::vector<float> line;
    if (!(double(r) <= limit_mm))
        return line;
    const auto limit = static_cast<float>(double(r) + 2.0 * std::max(m.spacing[0], m.spacing[1]));
    for (std::size_t i = 0; i < dp.data.size(); ++i)
        if (candidate(i) && std::max(dp.data[i], dk[i]) <= limit)
            line.push_back(smoothed.data[i]);
    return line;
}

//! Pieces that keep_liver_pieces dropped (`dropped`, taken out of `m`) but that a vessel cut
//! off: it touches the previous contour's `rim` (a lobe along the surface; a piece enclosed
//! within the contour stays dropped, an organ or the IVC's partial volume), and the tissue
//! between it and the kept pieces reads brighter than `hi` in
//! `smoothed` (median). "Between": the pixels in neither, within reach_mm of both, inside the
//! previous contour's `outline` with its holes filled (so not the fat outside the liver). A
//! contrast-filled vein crossing the liver is brighter than the parenchyma on both its sides; an
//! organ that took the liver's place meets it along a thin dark line (pericardium, capsule) or a
//! plain step. A piece with no pixel within reach_mm of both (a wide vein between widened edge
//! lines) is judged on the midline of its narrowest gap instead, if that lies within midline_mm of
//! both (there the gap may also cross a vein open to the surface). Such pieces go back into `m`
//! (and out of `dropped`); returns their pixels.
std::size_t restore_vessel_cut_pieces(core::LabelImage3D& m, core::LabelImage3D& dropped, const core::LabelImage3D& rim,
                                      const core::LabelImage3D& outline, const core::ImageF& smoothed, double hi,
                                      double reach_mm, double midline_mm)
{
    const int rx = std::max(1, static_cast<int>(std::lround(reach_mm / m.spacing[0])));
    const int ry = std::max(1, static_cast<int>(std::lround(reach_mm / m.spacing[1])));
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rx + 1, 2 * ry + 1));
    const core::LabelImage3D inside = filled(outline);
    cv::Mat kept(m.size[1], m.size[0], CV_8U, m.data.data()), near_kept;
    cv::dilate(kept, near_kept, disc);
    cv::Mat bin(dropped.size[1], dropped.size[0], CV_8U, dropped.data.data()), labels;
    const int n = cv::connectedComponents(bin, labels, 8, CV_32S);
    std::vector<std::size_t> back;
    std::optional<core::ImageF> to_kept; // for gap_midline; m changes only after the loop
    for (int l = 1; l < n; ++l) {
        const cv::Mat piece = labels == l;
        cv::Mat near_piece;
        cv::dilate(piece, near_piece, disc);
        std::vector<float> between;
        bool on_rim = false;
        for (std::size_t i = 0; i < m.data.size(); ++i) {
            on_rim = on_rim || (piece.data[i] && rim.data[i]);
            if (near_piece.data[i] && near_kept.data[i] && inside.data[i] && !m.data[i] && !dropped.data[i])
                between.push_back(smoothed.data[i]);
        }
        if (!on_rim)
            continue;
        // On the gap's midline the upper quartile: the narrowest gap may run past the vein's end
        // through liver that the edge lines cut from the start contour (liver-grey, not dark).
        std::size_t rank = between.size() / 2;
        if (between.empty() && midline_mm > reach_mm) {
            if (!to_kept)
                to_kept = euclidean_distance(m);
            between = gap_midline(piece, *to_kept, inside, m, dropped, smoothed, midline_mm, hi);
            rank = 3 * between.size() / 4;
        }
        if (between.empty())
            continue;
        const auto mid = between.begin() + static_cast<std::ptrdiff_t>(rank);
        std::nth_element(between.begin(), mid, between.end());
        if (double(*mid) <= hi)
            continue;
        for (std::size_t i = 0; i < m.data.size(); ++i)
            if (piece.data[i])
                back.push_back(i);
    }
    for (const std::size_t i : back) {
        m.data[i] = 1;
        dropped.data[i] = 0;
    }
    return back.size();
}

//! Edges of a slice that separate tissues of near-equal grey (the heart or kidney lying in a
//! concavity of the liver behind a thin contact line): hysteresis on the edge map with the
//! thresholds a few noise levels up (f's median is the noise gradient), widened by one pixel.
//! The pixels of mask `m` whose grey level in `smoothed` lies in [lo, hi], opened by r_mm (a
//! Euclidean erosion, then a dilation kept inside `m`): what of a contour reads as liver.
core::LabelImage3D liver_grey_core(const core::LabelImage3D& m, const core::ImageF& smoothed, double lo, double hi,
                                   double r_mm)
{
    core::LabelImage3D in(m.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        in.data[i] = m.data[i] && double(smoothed.data[i]) >= lo && double(smoothed.data[i]) <= hi ? 1 : 0;
    if (r_mm > 0)
        in = grow(shrink(in, r_mm), r_mm);
    for (std::size_t i = 0; i < in.data.size(); ++i)
        in.data[i] = in.data[i] && m.data[i] ? 1 : 0;
    return in;
}

core::LabelImage3D cut_lines(const core::ImageF& img, const EdgeMapParams& ep)
{
    const EdgeMapResult e = edge_map(img, ep);
    core::LabelImage3D edges = binary_edges(e.edge, noise_adapted(e.edge, BinaryEdgeParams{}, 3.0));
    cv::Mat m(edges.size[1], edges.size[0], CV_8U, edges.data.data());
    cv::dilate(m, m, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
    return edges;
}

//! The liver's grey level, estimated on the seed slice inside the seed.
struct Tissue {
    double mean = 0;
    double sigma = 1;
    double low(double k) const { return mean - k * sigma; }  //!< k standard deviations below the mean
    double high(double k) const { return mean + k * sigma; } //!< k standard deviations above the mean
};

Tissue tissue_under(const core::ImageF& smoothed, const core::LabelImage3D& m)
{
    double s = 0, s2 = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i)
        if (m.data[i]) {
            s += double(smoothed.data[i]);
            s2 += double(smoothed.data[i]) * double(smoothed.data[i]);
            ++n;
        }
    Tissue t;
    if (n == 0)
        return t;
    t.mean = s / double(n);
    t.sigma = std::sqrt(std::max(1e-6, s2 / double(n) - t.mean * t.mean));
    return t;
}

core::LabelImage3D band_of(const core::ImageF& smoothed, const Tissue& t, double alpha)
{
    core::LabelImage3D out(smoothed.geometry(), 0);
    const double lo = t.low(alpha), hi = t.high(alpha);
    for (std::size_t i = 0; i < out.data.size(); ++i)
        out.data[i] = double(smoothed.data[i]) >= lo && double(smoothed.data[i]) <= hi ? 1 : 0;
    return out;
}

//! A slice's edge snap, to be run later: the next slice starts from the unsnapped mask, so the
//! snap is off the propagation's sequential path and can run on whichever thread is free.
struct SnapJob {
    int slice = 0;
    core::ImageGeometry grid;       // the whole slice's
    Window window;                  // the snap's window on it
    core::ImageF image;             // the window of the image the snake saw (excluded organs are fat)
    core::LabelImage3D mask;        // the window of the mask to snap
    core::LabelImage3D excluded;    // the window of the organs left out (empty: none)
};

struct SliceOutcome {
    core::LabelImage3D mask;    // on the slice's geometry; the next slice starts from it
    core::LabelImage3D snapped; // the mask moved on to the edges (empty: as mask); it is stacked
    std::optional<SnapJob> snap; // the snap still to run (segment_slice leaves it to the caller)
    LiverSliceReport report;
    PieceLineage lineage; // the mask's separate pieces, for the next slice's growing-pieces rule
    bool stop = false;
};

//! Everything the per-slice step reads besides the slice: built once, shared by both threads.
struct Context {
    const core::ImageF& hu;
    const LiverParams& p;
    const LiverProgress& progress;
    const RibCageResult* ribs = nullptr;  //!< null: no rib cage
    const ShapeMemory* memory = nullptr;  //!< null: the fixed growth envelope
    int top_slice = -1;                   //!< slices >= this hold no liver (the heart/lung start slice); -1 = none
    Tissue tissue;                        //!< the liver's grey level (seed slice)
    Tissue band;                          //!< the grey levels under the seed slice's contour
                                          //!< (median, robust sd): the tissue stop's band
    bool band_measured = false;           //!< band holds the seed contour's levels (after the seed slice)
    bool downward = false;                //!< the propagation goes down (towards the tip)
    bool heart_known = false;             //!< the start slice found the heart at heart_i, heart_j
    double heart_i = 0, heart_j = 0;      //!< (continuous voxel index, in-plane)
};

//! The slice k as the snake sees it: outside the rib cage replaced by fat, so that a contour
//! creeping along the subcostal tissue meets a strong edge at the ribs' inner surface.
core::ImageF slice_image(const Context& c, int k)
{
    core::ImageF img = core::axial_slice(c.hu, k);
    if (c.ribs && c.ribs->valid[static_cast<std::size_t>(k)]) {
        const core::LabelImage3D inside = core::axial_slice(c.ribs->inside, k);
        img = mask_outside_rib_cage(img, inside, static_cast<float>(c.p.rib_background_hu));
    }
    return img;
}

//! The liver-like tissue of a window: the K-means layer nearest the liver's grey level (the
//! thesis's per-slice adaptive clustering), or the fixed band around the seed's statistics.
core::LabelImage3D liver_layer(const Context& c, const core::ImageF& smoothed)
{
    if (!c.p.use_kmeans)
        return band_of(smoothed, c.tissue, c.p.layer_alpha);
    const KMeansResult km = kmeans_layers(smoothed, c.p.kmeans);
    LayerParams lp = c.p.layer;
    lp.min_sigma = std::max(lp.min_sigma, c.tissue.sigma);
    LayerResult lr = layer_mask(smoothed, km, c.tissue.mean, lp);
    // The layer nearest the liver's grey level is not always liver-like: below the liver's tip
    // the window holds no liver, and the nearest layer is muscle and bowel (measured on the
    // default phantom: centre 13-23 HU, band -24..70 HU, against the liver's 105 HU), which the
    // propagation then followed for five slices under the liver. A layer whose acceptance band
    // does not hold the liver's own grey level is not the liver: no liver-like tissue on this
    // slice, and the liver ends here (the fixed band ends it on the same slice).
    if (!(lr.low <= c.tissue.mean && c.tissue.mean <= lr.high))
        std::fill(lr.mask.data.begin(), lr.mask.data.end(), std::uint8_t(0));
    return std::move(lr.mask);
}

double area_of(const core::LabelImage3D& m)
{
    return double(count(m)) * pixel_area_mm2(m.geometry());
}

//! Slice k of the volume, box-smoothed in-plane with half-width r pixels, as a CV_32F matrix.
cv::Mat smoothed_slice(const core::ImageF& v, int k, int r)
{
    core::ImageF s = core::axial_slice(v, k);
    cv::Mat m(s.size[1], s.size[0], CV_32F, s.data.data()), out;
    cv::blur(m, out, cv::Size(2 * r + 1, 2 * r + 1), cv::Point(-1, -1), cv::BORDER_REPLICATE);
    return out;
}

//! The dome contact above the liver mask `below` of slice k (docs/algorithms/liver.md): the
//! columns of `below` where slice k + 1 is a z-valley, min(v[k], v[k+2]) - v[k+1] deeper than
//! both contact_min_dip and contact_sigmas robust sd of that depth over `below`, closed with a
//! disc of contact_closing_mm. All zero when none.
core::LabelImage3D dome_contact(const Context& c, int k, const core::LabelImage3D& below)
{
    const LiverParams& p = c.p;
    core::LabelImage3D out(below.geometry(), 0);
    if (k + 2 >= c.hu.size[2] || count(below) == 0)
        return out;
    const double h = std::max(c.hu.spacing[0], c.hu.spacing[1]);
    const int r = std::max(1, static_cast<int>(std::lround(p.contact_smoothing_mm / h)));
    const cv::Mat s0 = smoothed_slice(c.hu, k, r), s1 = smoothed_slice(c.hu, k + 1, r),
                  s2 = smoothed_slice(c.hu, k + 2, r);
    cv::Mat depth;
    cv::subtract(cv::min(s0, s2), s1, depth);
    const auto* d = depth.ptr<float>(0);
    std::vector<float> in;
    for (std::size_t i = 0; i < below.data.size(); ++i)
        if (below.data[i])
            in.push_back(d[i]);
    const auto [med, sd] = detail::median_and_robust_sd(std::move(in));
    const double threshold = std::max(p.contact_min_dip, med + p.contact_sigmas * sd);
    cv::Mat valley(depth.rows, depth.cols, CV_8U, cv::Scalar(0));
    for (int i = 0; i < depth.rows * depth.cols; ++i)
        valley.data[i] = (below.data[static_cast<std::size_t>(i)] && double(d[i]) > threshold) ? 255 : 0;
    const int rc = std::max(1, static_cast<int>(std::lround(p.contact_closing_mm / h)));
    cv::morphologyEx(valley, valley, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rc + 1, 2 * rc + 1)));
    for (int i = 0; i < depth.rows * depth.cols; ++i)
        out.data[static_cast<std::size_t>(i)] = valley.data[i] ? 1 : 0;
    return out;
}

//! The pieces of the contact sheet `found` (the union of every dome contact found so far) of at
//! least contact_min_area_mm2: the heart's round base meets the dome along rings that widen
//! slice by slice, each too thin to tell from noise alone, and together one sheet.
core::LabelImage3D contact_sheet(const Context& c, core::LabelImage3D found)
{
    cv::Mat bin(found.size[1], found.size[0], CV_8U, found.data.data());
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(bin, labels, stats, centroids, 8, CV_32S);
    const double px = pixel_area_mm2(found.geometry());
    // Each piece large enough and under the heart stands for the heart's footprint: its convex
    // hull, since the rings are often open where a vessel crosses them.
    cv::Mat sheet(bin.rows, bin.cols, CV_8U, cv::Scalar(0));
    for (int l = 1; l < n; ++l) {
        if (stats.at<int>(l, cv::CC_STAT_AREA) * px < c.p.contact_min_area_mm2)
            continue;
        const double dx = (centroids.at<double>(l, 0) - c.heart_i) * found.spacing[0];
        const double dy = (centroids.at<double>(l, 1) - c.heart_j) * found.spacing[1];
        if (std::hypot(dx, dy) > c.p.contact_heart_radius_mm)
            continue;
        std::vector<cv::Point> pts;
        cv::findNonZero(labels == l, pts);
        std::vector<cv::Point> hull;
        cv::convexHull(pts, hull);
        cv::fillConvexPoly(sheet, hull, cv::Scalar(1));
    }
    std::copy(sheet.data, sheet.data + found.data.size(), found.data.begin());
    return found;
}

//! Vessel inlets (SLIVER07: vessels inside the liver are liver): on each slice of `mask`, the
//! voxels that a closing with radius `r_mm` adds and whose smoothed grey level is at least `hi`
//! (contrast-filled vessels), widened by one pixel within the closing for their partial-volume
//! walls, are added. Returns the voxels added.
std::size_t fill_vessel_inlets(const Context& c, core::LabelImage3D& mask, const std::vector<int>& slices, double r_mm,
                               double hi)
{
    const int rx = std::max(1, static_cast<int>(std::lround(r_mm / mask.spacing[0])));
    const int ry = std::max(1, static_cast<int>(std::lround(r_mm / mask.spacing[1])));
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * rx + 1, 2 * ry + 1));
    std::size_t added = 0;
    // Slices are independent (each writes its own plane of `mask`).
#pragma omp parallel for schedule(dynamic) reduction(+ : added)
    for (std::size_t n = 0; n < slices.size(); ++n) {
        const int k = slices[n];
        core::LabelImage3D m = core::axial_slice(mask, k);
        if (count(m) == 0)
            continue;
        const Window w = window_around(m, r_mm + 2.0 * std::max(mask.spacing[0], mask.spacing[1]));
        core::LabelImage3D mw = crop(m, w);
        const core::ImageF smooth = gaussian_smooth(crop(slice_image(c, k), w), 1.0);
        cv::Mat in(mw.size[1], mw.size[0], CV_8U, mw.data.data());
        cv::Mat closed, bright(in.size(), CV_8U, cv::Scalar(0));
        cv::morphologyEx(in, closed, cv::MORPH_CLOSE, disc);
        for (int j = 0; j < in.rows; ++j)
            for (int i = 0; i < in.cols; ++i)
                if (closed.at<uchar>(j, i) && !in.at<uchar>(j, i) && double(smooth.at(i, j, 0)) >= hi)
                    bright.at<uchar>(j, i) = 1;
        cv::dilate(bright, bright, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
        for (int j = 0; j < in.rows; ++j)
            for (int i = 0; i < in.cols; ++i)
                if (bright.at<uchar>(j, i) && closed.at<uchar>(j, i) && !in.at<uchar>(j, i)) {
                    mask.at(w.i0 + i, w.j0 + j, k) = 1;
                    ++added;
                }
    }
    return added;
}

//! The heart over the dome (docs/algorithms/liver.md, "The heart model"): the heart's blood pool,
//! found on the start slice as the bright (contrast-filled) piece nearest the template's heart
//! centre and followed down slice by slice while its pieces stay large (the IVC, which leaves the
//! right atrium downwards through the liver, is a small piece and is not followed), dilated in
//! 3-D by the myocardium's thickness. Empty without a start slice.
core::LabelImage3D heart_model(const Context& c, int lowest, double bright)
{
    const LiverParams& p = c.p;
    const core::ImageF& hu = c.hu;
    core::LabelImage3D blood(hu.geometry(), 0);
    if (!c.heart_known || c.top_slice < 0 || c.top_slice >= hu.size[2])
        return blood;
    const double px = pixel_area_mm2(hu.geometry());
    double largest = 0;
    core::LabelImage3D prev;
    for (int k = c.top_slice; k >= std::max(0, lowest); --k) {
        const core::ImageF sm = gaussian_smooth(core::axial_slice(hu, k), 1.0);
        cv::Mat bin(sm.size[1], sm.size[0], CV_8U, cv::Scalar(0));
        for (int j = 0; j < sm.size[1]; ++j)
            for (int i = 0; i < sm.size[0]; ++i) {
                const double v = sm.at(i, j, 0);
                bin.at<uchar>(j, i) = v >= bright && v <= p.heart_max_hu ? 1 : 0;
            }
        cv::Mat labels, stats, centroids;
        const int n = cv::connectedComponentsWithStats(bin, labels, stats, centroids, 8, CV_32S);
        std::vector<char> keep(static_cast<std::size_t>(n), 0);
        if (prev.data.empty()) {
            // The start slice: the piece nearest the heart centre, within the search radius.
            int best = 0;
            double best_d = p.heart_search_mm;
            for (int j = 0; j < labels.rows; ++j)
                for (int i = 0; i < labels.cols; ++i) {
                    const int l = labels.at<int>(j, i);
                    if (!l || stats.at<int>(l, cv::CC_STAT_AREA) * px < p.heart_min_area_mm2)
                        continue;
                    const double d = std::hypot((i - c.heart_i) * hu.spacing[0], (j - c.heart_j) * hu.spacing[1]);
                    if (d < best_d) {
                        best_d = d;
                        best = l;
                    }
                }
            if (!best)
                return blood;
            keep[static_cast<std::size_t>(best)] = 1;
        } else {
            // Below: the large pieces that overlap the blood of the slice above.
            for (int j = 0; j < labels.rows; ++j)
                for (int i = 0; i < labels.cols; ++i) {
                    const int l = labels.at<int>(j, i);
                    if (l && prev.at(i, j, 0) &&
                        stats.at<int>(l, cv::CC_STAT_AREA) * px >=
                            std::max(p.heart_min_area_mm2, p.heart_min_area_fraction * largest))
                        keep[static_cast<std::size_t>(l)] = 1;
                }
        }
        core::LabelImage3D cur(sm.geometry(), 0);
        double area = 0;
        for (int j = 0; j < labels.rows; ++j)
            for (int i = 0; i < labels.cols; ++i)
                if (keep[static_cast<std::size_t>(labels.at<int>(j, i))]) {
                    cur.at(i, j, 0) = 1;
                    blood.at(i, j, k) = 1;
                    area += px;
                }
        if (area <= 0)
            break;
        largest = std::max(largest, area);
        prev = std::move(cur);
    }
    if (detail::bounding_box(blood).empty())
        return blood;
    // The myocardium: everything within the wall thickness of the blood pool, in 3-D.
    const detail::Box b = detail::grown(detail::bounding_box(blood), detail::voxels_for(hu.geometry(), p.heart_wall_mm),
                                        hu.geometry());
    const core::LabelImage3D part = detail::crop(blood, b);
    const core::ImageF d = euclidean_distance(part);
    core::LabelImage3D grown_part(part.geometry(), 0);
    for (std::size_t i = 0; i < d.data.size(); ++i)
        grown_part.data[i] = double(d.data[i]) <= p.heart_wall_mm ? 1 : 0;
    core::LabelImage3D model(hu.geometry(), 0);
    detail::paste(model, grown_part, b);
    return model;
}

//! How far a contour may move out between slices dz apart without a shape memory [mm].
double growth_bound_mm(const LiverParams& p, double dz)
{
    return p.max_growth_per_mm * dz + p.growth_slack_mm;
}

//! Segments slice k from the previous slice's accepted mask, or from the seed (previous null).
SliceOutcome segment_slice(const Context& c, int k, const core::LabelImage3D& start, const core::LabelImage3D* previous,
                           double largest_area_mm2, const core::LabelImage3D* above_contact = nullptr,
                           const core::LabelImage3D* heart = nullptr, const PieceLineage* lineage = nullptr)
{
    const LiverParams& p = c.p;
    const auto t0 = Clock::now();
    SliceOutcome out;
    out.report.slice = k;
    core::ImageF img = slice_image(c, k);
    const core::ImageGeometry& g = img.geometry();
    core::LabelImage3D excluded; // organs that took the liver's place on this slice
    const double px = pixel_area_mm2(g);
    core::LabelImage3D init = on_grid(start, g);
    core::LabelImage3D templ;
    core::LabelImage3D region; // with layer_holds_pressure: the liver-like layer, where the pressure acts
    if (previous) {
        templ = on_grid(*previous, g);
        const Window ww = window_around(templ, p.window_margin_mm);
        const core::ImageF img_w = crop(img, ww);
        const core::ImageF smooth_w = gaussian_smooth(img_w, 1.0);
        const core::LabelImage3D layer = liver_layer(c, smooth_w);
        if (p.layer_holds_pressure) {
            region = core::LabelImage3D(g, 0);
            paste(layer, ww, region);
        }
        if (p.envelope_holds_pressure) {
            // The outline may not move further than the envelope allows (the memory's, or the
            // fixed growth bound): outside it the pressure is zero, so the front stops there
            // instead of being clipped after the run.
            const core::LabelImage3D env = c.memory && p.use_shape_memory
                                               ? plausible_envelope(*c.memory, templ, c.hu.spacing[2], largest_area_mm2)
                                               : grow(templ, growth_bound_mm(p, c.hu.spacing[2]));
            if (region.data.empty())
                region = env;
            else
                for (std::size_t i = 0; i < region.data.size(); ++i)
                    region.data[i] = region.data[i] && env.data[i];
        }
        const core::LabelImage3D lines = cut_lines(img_w, p.snake.edge);
        // Shrunk inside the window, not the slice: the window holds the contour with a margin of
        // outside pixels, which are each inside pixel's nearest outside at least as near as any
        // beyond it, so the erosion is the same at a quarter of the cost.
        const core::LabelImage3D shrunk = shrink(crop(templ, ww), p.erosion_mm);
        // The rim: the shrunk previous contour's outermost two pixels.
        core::LabelImage3D rim = shrink(shrunk, 2.0 * std::max(g.spacing[0], g.spacing[1]));
        for (std::size_t i = 0; i < rim.data.size(); ++i)
            rim.data[i] = shrunk.data[i] && !rim.data[i];
        core::LabelImage3D init_w = shrunk;
        for (std::size_t i = 0; i < init_w.data.size(); ++i)
            init_w.data[i] = init_w.data[i] && layer.data[i] && !lines.data[i];
        // The previous contour, cut along the slice's edges, falls into pieces. An organ that
        // took the liver's place (the heart over the dome, the kidney under it) is a piece
        // enclosed inside it, and is left out; a lobe cut off by a vessel lies along the rim.
        core::LabelImage3D dropped = keep_liver_pieces(
            init_w, rim, static_cast<int>(std::ceil(p.min_seed_area_mm2 / px)), p.keep_piece_fraction, p.rim_piece_fraction);
        if (p.keep_vessel_cut_pieces && count(dropped) > 0)
            out.report.vessel_cut_mm2 =
                px * double(restore_vessel_cut_pieces(init_w, dropped, rim, crop(templ, ww), smooth_w,
                                                      c.band.high(p.tissue_stop_sigmas),
                                                      p.vessel_cut_reach_mm, p.vessel_cut_midline_reach_mm));
        // The kept pieces start the snake only where they hold the liver's own grey levels (the
        // layer clip): the K-means layer is 2.4-4.4 times wider than the seed contour's band and
        // holds the partial volume with fat and the brighter neighbours (the IVC, a kidney's pole)
        // where they touch the liver. The pieces are judged on the whole layer first: a layer
        // clipped before the rule falls into more, smaller pieces, and the rule's choice of them
        // cost the 0.7 mm grids 1-3 points (docs/algorithms/liver.md, "The layer clip").
        if (p.layer_clip_sigmas > 0.0 && c.band_measured) {
            const double lo = c.band.low(p.layer_clip_sigmas), hi = c.band.high(p.layer_clip_sigmas);
            for (std::size_t i = 0; i < init_w.data.size(); ++i)
                if (double(smooth_w.data[i]) < lo || double(smooth_w.data[i]) > hi)
                    init_w.data[i] = 0;
        }
        if (count(init_w) == 0) {
            out.stop = true; // no liver-like tissue left under the previous contour: the liver ended
            return out;
        }
        init = core::LabelImage3D(g, 0);
        paste(init_w, ww, init);
        if (p.exclude_dropped_pieces && count(dropped) > 0) {
            excluded = core::LabelImage3D(g, 0);
            paste(dropped, ww, excluded);
        }
    }
    // The columns above a dome contact and the heart model's on this slice are closed too;
    // returns the area closed.
    const auto close_off = [&](const core::LabelImage3D* closed) {
        if (!closed || count(*closed) == 0)
            return 0.0;
        if (excluded.data.empty())
            excluded = core::LabelImage3D(g, 0);
        for (std::size_t i = 0; i < excluded.data.size(); ++i)
            excluded.data[i] = excluded.data[i] || closed->data[i];
        return area_of(*closed);
    };
    out.report.above_contact_mm2 = close_off(above_contact);
    out.report.heart_mm2 = close_off(heart);
    const bool contact = out.report.above_contact_mm2 > 0;
    // The snake must not flow back into an excluded organ (or above a dome contact) through its
    // faint contact line: to it the region looks like fat (a strong edge), and the contour is
    // cut there; the start contour leaves it out.
    if (!excluded.data.empty())
        for (std::size_t i = 0; i < img.data.size(); ++i)
            if (excluded.data[i]) {
                img.data[i] = static_cast<float>(p.rib_background_hu);
                init.data[i] = 0;
            }
    if ((contact || out.report.heart_mm2 > 0) && count(init) == 0) {
        out.stop = true;
        return out;
    }

    // Only a window around the contour is modelled: the liver moves a few mm per slice, and
    // fields, edges and the level set cost in proportion to the pixels they cover.
    Window w = window_around(previous ? templ : init,
                             previous ? p.window_growth_per_mm * c.hu.spacing[2] + p.window_margin_mm : p.seed_window_mm);
    SnakeParams sp = p.snake;
    if (previous)
        sp.level_set.max_iterations = propagation_iteration_bound(p, c.hu.spacing[0], c.hu.spacing[1]);
    const auto run_snake = [&](const Window& win) {
        const core::LabelImage3D templ_w = previous ? crop(templ, win) : core::LabelImage3D();
        const core::LabelImage3D region_w = region.data.empty() ? core::LabelImage3D() : crop(region, win);
        return segment_snake(crop(img, win), crop(init, win), sp, previous ? &templ_w : nullptr,
                             region_w.data.empty() ? nullptr : &region_w);
    };
    SnakeResult r = run_snake(w);
    if (!previous && p.widen_seed_window && reaches_inner_edge(r.mask, w, g)) {
        // The seed's contour stopped at its window's edge, not at the liver's: the left lobe lies
        // far from a seed on the right (on every phantom it was cut there). Run again on the
        // whole slice; a contour that stopped inside its window keeps it, since the window's
        // size sets the snake's edge thresholds (docs/algorithms/liver.md).
        const Window whole{0, 0, g.size[0], g.size[1]};
        SnakeResult wider = run_snake(whole);
        // ... unless the whole slice's contour does not hold the window's: then the changed
        // thresholds, not the window, decided it (a shaded MR's dim far side).
        core::LabelImage3D in_window(g, 0);
        paste(r.mask, w, in_window);
        std::size_t held = 0;
        for (std::size_t i = 0; i < in_window.data.size(); ++i)
            held += in_window.data[i] && wider.mask.data[i];
        if (double(held) >= p.seed_window_hold * double(count(in_window))) {
            w = whole;
            r = std::move(wider);
            out.report.seed_window_widened = true;
        }
    }
    out.mask = core::LabelImage3D(g, 0);
    paste(r.mask, w, out.mask);
    out.report.iterations = r.iterations;
    out.report.converged = r.converged;
    out.report.leak_stopped = r.leak_stopped;
    out.report.competition_used = r.competition_used;

    if (previous) {
        const double dz = c.hu.spacing[2];
        if (c.memory && p.use_shape_memory) {
            // The memory's verdict; a rejected contour is clipped to the envelope the memory
            // allows around the previous one (a leak is cut at the learnt boundary motion).
            ShapeCheck check = check_slice(*c.memory, templ, out.mask, dz, largest_area_mm2);
            out.report.shape_score = check.score;
            if (!check.plausible) {
                out.report.rejected = true;
                out.report.shape_reason = check.reason;
                const core::LabelImage3D env = plausible_envelope(*c.memory, templ, dz, largest_area_mm2);
                for (std::size_t i = 0; i < out.mask.data.size(); ++i)
                    out.mask.data[i] = out.mask.data[i] && env.data[i];
                check = check_slice(*c.memory, templ, out.mask, dz, largest_area_mm2);
                out.report.recovered = check.plausible;
            }
        } else {
            // Without a memory the outline may move at most max_growth_per_mm per mm of z plus
            // the slack. The mask lies inside the snake's window, which holds all of the previous
            // contour, so the envelope is needed, and exact, there only.
            core::LabelImage3D mask_w = crop(out.mask, w);
            const core::LabelImage3D envelope = grow(crop(templ, w), growth_bound_mm(p, c.hu.spacing[2]));
            for (std::size_t i = 0; i < mask_w.data.size(); ++i)
                mask_w.data[i] = mask_w.data[i] && envelope.data[i];
            paste(mask_w, w, out.mask);
        }
    }
    if (!excluded.data.empty())
        for (std::size_t i = 0; i < out.mask.data.size(); ++i)
            out.mask.data[i] = out.mask.data[i] && !excluded.data[i];
    out.report.area_mm2 = area_of(out.mask);
    if (previous && p.drop_growing_pieces) {
        // Past the widest slice the liver's cross-sections shrink (the dome and the tip are
        // convex); a separate piece that grows is something carried along beside it.
        const bool past_widest = out.report.area_mm2 < 0.9 * largest_area_mm2;
        out.report.grown_pieces_mm2 =
            double(drop_growing_pieces(out.mask, templ, lineage ? *lineage : PieceLineage{}, out.lineage, past_widest,
                                       p.piece_growth_limit,
                                       c.downward ? p.piece_lineage_limit : std::numeric_limits<double>::infinity())) *
            px;
        out.report.area_mm2 = area_of(out.mask);
    }
    if (previous && p.use_tissue_stop) {
        // The liver's parenchyma is homogeneous: a contour mostly outside its grey levels has
        // crossed into something else at the liver's end (bowel with gas and fat, a kidney).
        const core::ImageF smooth_w = gaussian_smooth(crop(img, w), 1.0);
        const core::LabelImage3D mask_w = crop(out.mask, w);
        const double lo = c.band.low(p.tissue_stop_sigmas), hi = c.band.high(p.tissue_stop_sigmas);
        std::size_t in = 0, outside = 0;
        for (std::size_t i = 0; i < mask_w.data.size(); ++i)
            if (mask_w.data[i]) {
                ++in;
                const double v = smooth_w.data[i];
                outside += v < lo || v > hi;
            }
        out.report.outside_fraction = in ? double(outside) / double(in) : 0.0;
        if (p.trim_at_tissue_stop && out.report.outside_fraction > p.tissue_stop_fraction) {
            const core::LabelImage3D core_w =
                liver_grey_core(mask_w, smooth_w, lo, hi, p.tissue_trim_opening_px * std::max(g.spacing[0], g.spacing[1]));
            const std::size_t kept = count(core_w);
            if (double(kept) >= p.tissue_trim_keep * double(in) &&
                double(kept) * px >= p.tissue_trim_min_area_fraction * largest_area_mm2) {
                out.report.tissue_trim_mm2 = double(in - kept) * px;
                std::fill(out.mask.data.begin(), out.mask.data.end(), std::uint8_t(0));
                paste(core_w, w, out.mask);
                out.report.area_mm2 = area_of(out.mask);
            }
        }
        if (out.report.tissue_trim_mm2 == 0.0 && out.report.outside_fraction > p.tissue_stop_fraction) {
            out.report.not_liver = true;
            out.stop = true;
            std::fill(out.mask.data.begin(), out.mask.data.end(), std::uint8_t(0));
        }
    }
    if (p.use_edge_snap && !out.report.not_liver && out.report.area_mm2 >= p.min_area_mm2) {
        // Within the snake's window, on the image the snake saw (excluded organs are fat there).
        const Window sw = window_around(out.mask, p.window_margin_mm);
        core::LabelImage3D mask_sw = crop(out.mask, sw);
        if (count(mask_sw) < mask_sw.data.size()) // a contour filling its window has no edge to meet
            out.snap = SnapJob{k, g, sw, crop(img, sw), std::move(mask_sw),
                               excluded.data.empty() ? core::LabelImage3D() : crop(excluded, sw)};
    }
    out.report.seconds = seconds_since(t0);
    if (out.report.area_mm2 < p.min_area_mm2)
        out.stop = true;
    return out;
}

void report(const Context& c, const LiverSliceReport& r)
{
    if (!c.progress)
        return;
    std::ostringstream s;
    s.precision(3);
    s << "slice " << r.slice << ": " << r.area_mm2 / 100.0 << " cm2, " << r.iterations << " iterations"
      << (r.converged      ? ""
          : r.leak_stopped ? " (leak stop)"
                           : " (bound)")
      << (r.competition_used ? ", competition" : "")
      << (r.seed_window_widened ? ", on the whole slice (the seed's window cut it)" : "")
      << (r.rejected ? (r.recovered ? ", clipped by the shape memory (" : ", implausible even clipped (") +
                           r.shape_reason + ")"
                     : "")
      << (r.heart_mm2 > 0 ? ", " + std::to_string(static_cast<int>(std::lround(r.heart_mm2 / 100))) +
                                  " cm2 of the heart model"
                            : "")
      << (r.above_contact_mm2 > 0 ? ", " + std::to_string(static_cast<int>(std::lround(r.above_contact_mm2 / 100))) +
                                        " cm2 above a dome contact"
                                  : "")
      << (r.grown_pieces_mm2 > 0 ? ", " + std::to_string(static_cast<int>(std::lround(r.grown_pieces_mm2 / 100))) +
                                       " cm2 of separate pieces dropped (they grew past the widest slice)"
                                 : "")
      << (r.not_liver ? ", " + std::to_string(static_cast<int>(std::lround(100 * r.outside_fraction))) +
                            " % outside the liver's grey levels: not liver, the liver ends here"
                      : "")
      << (r.tissue_trim_mm2 > 0 ? ", " + std::to_string(static_cast<int>(std::lround(100 * r.outside_fraction))) +
                                      " % outside the liver's grey levels: trimmed to its liver-grey core (" +
                                      std::to_string(static_cast<int>(std::lround(r.tissue_trim_mm2 / 100))) +
                                      " cm2 dropped)"
                                : "")
      << ", " << r.seconds << " s";
    c.progress(s.str());
}

//! The snapped mask of a job, on the whole slice.
core::LabelImage3D run_snap(const LiverParams& p, const SnapJob& job)
{
    SnakeResult r = snap_to_edges(job.image, job.mask, p.snake,
                                  liver_snap_params(p, job.grid.spacing[0], job.grid.spacing[1]));
    if (!job.excluded.data.empty())
        for (std::size_t i = 0; i < r.mask.data.size(); ++i)
            r.mask.data[i] = r.mask.data[i] && !job.excluded.data[i];
    core::LabelImage3D out(job.grid, 0);
    paste(r.mask, job.window, out);
    return out;
}

//! The edge snaps of the propagation, run by whichever thread is free: the two directions push
//! their slices' snaps and run them once their own propagation has ended, so the direction that
//! ends first takes over the other's snaps instead of leaving its core idle. Each job writes
//! only its own slice's result, so the results do not depend on which thread ran them.
class SnapQueue {
  public:
    SnapQueue(const LiverParams& p, int slices, int producers) : p_(p), results_(std::size_t(slices)), producers_(producers) {}

    void push(SnapJob job)
    {
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            jobs_.push_back(std::move(job));
        }
        ready_.notify_one();
    }

    //! A producer has pushed its last job.
    void producer_done()
    {
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            --producers_;
        }
        ready_.notify_all();
    }

    //! Runs jobs until none is left and no producer will push more; a failed job's exception
    //! is kept for rethrow() and the others still run.
    void drain()
    {
        for (;;) {
            SnapJob job;
            {
                std::unique_lock<std::mutex> lock(mutex_);
                ready_.wait(lock, [&] { return !jobs_.empty() || producers_ == 0; });
                if (jobs_.empty())
                    return;
                job = std::move(jobs_.front());
                jobs_.pop_front();
            }
            try {
                results_[std::size_t(job.slice)] = run_snap(p_, job);
            } catch (...) {
                const std::lock_guard<std::mutex> lock(mutex_);
                if (!failure_)
                    failure_ = std::current_exception();
            }
        }
    }

    void rethrow() const
    {
        if (failure_)
            std::rethrow_exception(failure_);
    }

    //! The snapped mask of slice k (empty: not snapped).
    core::LabelImage3D take(int k) { return std::move(results_[std::size_t(k)]); }

  private:
    const LiverParams& p_;
    std::vector<core::LabelImage3D> results_;
    std::mutex mutex_;
    std::condition_variable ready_;
    std::deque<SnapJob> jobs_;
    int producers_;
    std::exception_ptr failure_;
};

LiverResult propagate(const Context& c, const core::LabelImage3D& seed, int seed_slice)
{
    const core::ImageF& hu = c.hu;
    const LiverParams& params = c.p;
    const auto t0 = Clock::now();
    LiverResult result;
    result.mask = core::LabelImage3D(hu.geometry(), 0);
    result.seed_slice = seed_slice;
    result.propagation_iterations = propagation_iteration_bound(params, hu.spacing[0], hu.spacing[1]);
    if (params.use_edge_snap) {
        const SnapParams sp = liver_snap_params(params, hu.spacing[0], hu.spacing[1]);
        result.snap_band = sp.band;
        result.snap_iterations = sp.iterations;
    }

    SliceOutcome first = segment_slice(c, seed_slice, seed, nullptr, 0.0);
    report(c, first.report);
    SnapQueue snaps(params, hu.size[2], 2);
    if (first.snap)
        snaps.push(std::move(*first.snap));
    const double first_area = first.report.area_mm2;
    // The slices after the seed's read the liver's grey levels from its whole contour: the seed
    // cells are few and homogeneous, and their sd is narrower than the liver's shading.
    Context cx = c;
    {
        const core::ImageF smooth = gaussian_smooth(slice_image(c, seed_slice), 1.0);
        std::vector<float> under;
        for (std::size_t i = 0; i < first.mask.data.size(); ++i)
            if (first.mask.data[i])
                under.push_back(smooth.data[i]);
        const auto [median, sd] = detail::median_and_robust_sd(std::move(under));
        cx.band = {median, sd};
        cx.band_measured = true;
    }

    core::LabelImage3D heart;
    if (params.use_heart_model && cx.heart_known) {
        const auto th = Clock::now();
        heart = heart_model(cx, seed_slice + 1, cx.band.high(params.vessel_inlet_sigmas));
        result.heart_model_voxels = count(heart);
        result.timings.emplace_back("heart model", seconds_since(th));
        if (c.progress) {
            std::ostringstream m;
            m.precision(3);
            m << "heart model: " << result.heart_model_voxels << " voxels closed to the upward propagation, "
              << seconds_since(th) << " s";
            c.progress(m.str());
        }
    }
    std::vector<SliceOutcome> up, down;
    auto run = [&](int step, std::vector<SliceOutcome>& out) {
        const core::LabelImage3D* prev = &first.mask;
        const PieceLineage* lineage = nullptr;
        double largest = first_area;
        const int end = c.top_slice >= 0 ? std::min(hu.size[2], c.top_slice) : hu.size[2];
        // Upward only: the columns closed by a dome contact found on slice j + 1 (applied from j + 2).
        const bool contacts = step > 0 && params.use_dome_contact && c.heart_known;
        core::LabelImage3D found, closed, pending;
        if (contacts)
            pending = dome_contact(cx, seed_slice, first.mask);
        Context cd = cx;
        cd.downward = step < 0;
        for (int k = seed_slice + step; k >= 0 && k < end; k += step) {
            const core::LabelImage3D heart_k =
                step > 0 && !heart.data.empty() ? core::axial_slice(heart, k) : core::LabelImage3D();
            SliceOutcome s = segment_slice(cd, k, *prev, prev, largest, closed.data.empty() ? nullptr : &closed,
                                           heart_k.data.empty() ? nullptr : &heart_k, lineage);
            if (s.mask.data.empty())
                break;
            if (s.snap)
                snaps.push(std::move(*s.snap));
            out.push_back(std::move(s));
            // A lineage is read by the next slice only: free the one before (two slice-sized
            // float images per slice, 290 MB over a 512 x 512 x 200 volume if all were kept).
            if (out.size() >= 2)
                out[out.size() - 2].lineage = PieceLineage{};
            report(cx, out.back().report);
            prev = &out.back().mask;
            lineage = &out.back().lineage;
            largest = std::max(largest, out.back().report.area_mm2);
            if (out.back().stop)
                break;
            if (contacts) {
                if (count(pending) > 0) {
                    if (found.data.empty())
                        found = pending;
                    else
                        for (std::size_t i = 0; i < found.data.size(); ++i)
                            found.data[i] = found.data[i] || pending.data[i];
                    closed = contact_sheet(cx, found);
                }
                pending = dome_contact(cx, k, out.back().mask);
            }
        }
    };
    // A direction that has ended runs the edge snaps still queued, the other direction's too.
    auto run_then_snap = [&](int step, std::vector<SliceOutcome>& out) {
        try {
            run(step, out);
        } catch (...) {
            snaps.producer_done();
            throw;
        }
        snaps.producer_done();
        snaps.drain();
    };
    if (params.parallel_directions) {
        // One direction per core; each snake then runs its OpenMP loops on one thread, since
        // two teams of two spinning threads on two cores make both slower. (Handing the idle
        // core to the direction still running was tried: a 512^2 slice's snake gains nothing
        // from a second thread, docs/benchmarks.md. The edge snaps are what it takes over.)
        const int outer = omp_get_max_threads();
        omp_set_num_threads(1);
        std::exception_ptr failed;
        std::thread t([&] {
            omp_set_num_threads(1);
            try {
                run_then_snap(+1, up);
            } catch (...) {
                failed = std::current_exception();
            }
        });
        try {
            run_then_snap(-1, down);
        } catch (...) {
            t.join();
            omp_set_num_threads(outer);
            throw;
        }
        t.join();
        omp_set_num_threads(outer);
        if (failed)
            std::rethrow_exception(failed);
    } else {
        run(+1, up);
        snaps.producer_done();
        run(-1, down);
        snaps.producer_done();
        snaps.drain();
    }
    snaps.rethrow();
    first.snapped = snaps.take(first.report.slice);
    for (auto* side : {&up, &down})
        for (auto& s : *side)
            s.snapped = snaps.take(s.report.slice);

    const std::size_t plane = static_cast<std::size_t>(hu.size[0]) * static_cast<std::size_t>(hu.size[1]);
    auto place = [&](const SliceOutcome& s) {
        const core::LabelImage3D& m = s.snapped.data.empty() ? s.mask : s.snapped;
        std::copy(m.data.begin(), m.data.end(),
                  result.mask.data.begin() +
                      static_cast<std::ptrdiff_t>(plane * static_cast<std::size_t>(s.report.slice)));
        result.slices.push_back(s.report);
    };
    for (auto it = down.rbegin(); it != down.rend(); ++it)
        place(*it);
    place(first);
    for (const auto& s : up)
        place(s);
    // Stacked: the slices' own masks (two byte images each) are not needed beside the steps below.
    std::vector<SliceOutcome>().swap(up);
    std::vector<SliceOutcome>().swap(down);
    if (params.fill_vessel_inlets && params.post.convention == LiverConvention::Sliver07) {
        // Contrast-filled vessels open to the liver's surface in a slice (hepatic veins running
        // to the IVC, portal branches at the hilum) are inlets the contour leaves out and the
        // 3-D pass's hole filling cannot reach.
        const auto tv = Clock::now();
        std::vector<int> ks;
        for (const auto& s : result.slices)
            ks.push_back(s.slice);
        result.vessel_inlet_voxels = fill_vessel_inlets(cx, result.mask, ks, params.vessel_inlet_closing_mm,
                                                        cx.band.high(params.vessel_inlet_sigmas));
        result.timings.emplace_back("vessel inlets", seconds_since(tv));
    }
    const bool lesions = params.fill_surface_lesions && params.post.convention == LiverConvention::Sliver07;
    const double band_low = cx.band.low(std::abs(params.tissue_stop_sigmas));
    DarkRimResult rim;
    if (params.trim_dark_rim || lesions) {
        // The contour's rim may hold a layer of darker tissue that it crossed at a weak edge
        // (the diaphragm between the liver and the ribs): dropped before the 3-D pass. The
        // surface lesions need its level even when it is off.
        const auto td = Clock::now();
        rim = trim_dark_rim(hu, result.mask, cx.band.mean, band_low, params.dark_rim);
        if (params.trim_dark_rim) {
            result.mask = std::move(rim.mask);
            result.dark_rim_voxels = rim.removed;
            result.dark_rim_level = rim.level;
            result.dark_rim_neighbour = rim.neighbour;
            result.dark_rim_touching_kept = rim.touching_kept;
            result.timings.emplace_back("dark rim", seconds_since(td));
        }
        if (c.progress && rim.applied && params.trim_dark_rim) {
            std::ostringstream m;
            m.precision(3);
            m << "dark rim: " << rim.removed << " voxels darker than " << rim.level
              << " along the contour's rim dropped (liver " << cx.band.mean << ", darker tissue outside "
              << rim.neighbour << (rim.touching_kept ? "" : "; pixels touching the liver included") << "), "
              << seconds_since(td) << " s";
            c.progress(m.str());
        }
    }
    if (lesions && rim.applied && rim.level < band_low) {
        // A hypodense lesion at the surface is a notch the contour runs round; under SLIVER07 it
        // is liver, and the tumour step looks only inside the liver.
        const auto tl = Clock::now();
        SurfaceLesionResult sl = fill_surface_lesions(hu, result.mask, rim.level, band_low,
                                                      heart.data.empty() ? nullptr : &heart, params.surface_lesions);
        result.mask = std::move(sl.mask);
        result.surface_lesion_voxels = sl.added;
        result.timings.emplace_back("surface lesions", seconds_since(tl));
        if (c.progress) {
            std::ostringstream m;
            m.precision(3);
            m << "surface lesions: " << result.surface_lesion_voxels << " voxels between " << rim.level << " and "
              << band_low << " in the contour's notches added, " << seconds_since(tl) << " s";
            c.progress(m.str());
        }
    }
    result.first_slice = result.slices.front().slice;
    result.last_slice = result.slices.back().slice;
    result.timings.emplace_back("propagate", seconds_since(t0));
    return result;
}

double volume_ml(const core::LabelImage3D& m)
{
    return double(count(m)) * m.spacing[0] * m.spacing[1] * m.spacing[2] / 1000.0;
}

void check_image(const core::ImageF& hu, const char* who)
{
    if (hu.data.empty() || hu.voxel_count() != hu.data.size())
        throw core::InvalidInputError(std::string(who) + ": the image is empty or its data does not match its size");
    for (float v : hu.data)
        if (!std::isfinite(v))
            throw core::InvalidInputError(std::string(who) + ": the image has non-finite values");
}

} // namespace

const char* modality_name(Modality modality)
{
    switch (modality) {
    case Modality::Ct:
        return "CT";
    case Modality::Mr:
        return "MR";
    case Modality::Auto:
        break;
    }
    return "auto";
}

Modality detect_modality(const core::ImageF& volume, double ct_air_fraction)
{
    if (volume.data.empty())
        throw core::InvalidInputError("detect_modality: the image is empty");
    if (!(ct_air_fraction > 0.0 && ct_air_fraction <= 1.0))
        throw core::InvalidInputError("detect_modality: ct_air_fraction must be in (0, 1], is " +
                                      std::to_string(ct_air_fraction));
    const auto air = std::count_if(volume.data.begin(), volume.data.end(), [](float v) { return v < -500.f; });
    return double(air) >= ct_air_fraction * double(volume.data.size()) ? Modality::Ct : Modality::Mr;
}

core::ImageF mr_liver_contrast(const core::ImageF& mr, double liver_value, double liver_sigma, double noise_hu)
{
    if (!std::isfinite(liver_value) || !(liver_sigma > 0.0) || !std::isfinite(liver_sigma) || !(noise_hu > 0.0) ||
        !std::isfinite(noise_hu))
        throw core::InvalidInputError("mr_liver_contrast: the liver value must be finite and liver_sigma and noise_hu "
                                      "positive (are " +
                                      std::to_string(liver_value) + ", " + std::to_string(liver_sigma) + ", " +
                                      std::to_string(noise_hu) + ")");
    core::ImageF out = mr;
    const double s = noise_hu / liver_sigma;
    for (float& v : out.data)
        v = static_cast<float>(std::max(-1000.0, 100.0 - s * std::abs(double(v) - liver_value)));
    return out;
}

namespace {

void check_pixel(double pixel_x_mm, double pixel_y_mm)
{
    if (!(pixel_x_mm > 0.0 && std::isfinite(pixel_x_mm) && pixel_y_mm > 0.0 && std::isfinite(pixel_y_mm)))
        throw core::InvalidInputError("segment_liver: the pixel spacing must be finite and > 0 (is " +
                                      std::to_string(pixel_x_mm) + " x " + std::to_string(pixel_y_mm) + " mm)");
}

// A count scaled to the pixel, rounded, at least 1. The callers keep their own expression order:
// at exact halves (1.6 mm pixels for the bound, 0.6 mm for the snap) the order decides the rounding.
int rounded_count(double scaled)
{
    return static_cast<int>(std::clamp(std::lround(scaled), 1L, long(std::numeric_limits<int>::max())));
}

} // namespace

int propagation_iteration_bound(const LiverParams& params, double pixel_x_mm, double pixel_y_mm)
{
    const double ref = params.propagation_reference_pixel_mm;
    if (params.propagation_max_iterations < 1 || !std::isfinite(ref) || ref < 0.0)
        throw core::InvalidInputError("segment_liver: propagation_max_iterations must be >= 1 and "
                                      "propagation_reference_pixel_mm finite and >= 0 (are " +
                                      std::to_string(params.propagation_max_iterations) + ", " + std::to_string(ref) +
                                      ")");
    check_pixel(pixel_x_mm, pixel_y_mm);
    if (ref == 0.0)
        return params.propagation_max_iterations;
    return rounded_count(params.propagation_max_iterations * ref / std::sqrt(pixel_x_mm * pixel_y_mm));
}

SnapParams liver_snap_params(const LiverParams& params, double pixel_x_mm, double pixel_y_mm)
{
    const double ref = params.snap_reference_pixel_mm;
    if (params.snap.band < 1 || params.snap.iterations < 1 || !std::isfinite(ref) || ref < 0.0)
        throw core::InvalidInputError("segment_liver: the edge snap's band and iterations must be >= 1 and "
                                      "snap_reference_pixel_mm finite and >= 0 (are " +
                                      std::to_string(params.snap.band) + ", " + std::to_string(params.snap.iterations) +
                                      ", " + std::to_string(ref) + ")");
    check_pixel(pixel_x_mm, pixel_y_mm);
    SnapParams s = params.snap;
    if (ref == 0.0)
        return s;
    const double scale = ref / std::sqrt(pixel_x_mm * pixel_y_mm);
    s.band = rounded_count(s.band * scale);
    s.iterations = rounded_count(s.iterations * scale);
    return s;
}

SnakeParams default_liver_snake()
{
    SnakeParams p;
    p.method = SnakeMethod::Cdsg;
    p.competition = CompetitionMode::Auto;
    return p;
}

namespace {

//! The seed propagate_liver is given: one slice of the image's size, on a slice of it, not empty.
void check_seed(const core::ImageF& hu, const core::LabelImage3D& seed, int seed_slice)
{
    if (seed_slice < 0 || seed_slice >= hu.size[2])
        throw core::InvalidInputError("propagate_liver: seed slice " + std::to_string(seed_slice) +
                                      " is outside the image (0.." + std::to_string(hu.size[2] - 1) + ")");
    if (seed.size[0] != hu.size[0] || seed.size[1] != hu.size[1] || seed.size[2] != 1 ||
        seed.data.size() != static_cast<std::size_t>(hu.size[0]) * static_cast<std::size_t>(hu.size[1]))
        throw core::InvalidInputError("propagate_liver: the seed must be one slice of the image's size");
    if (count(seed) == 0)
        throw core::InvalidInputError("propagate_liver: the seed is empty");
}

LiverResult propagate_head_up(const core::ImageF& hu, const core::LabelImage3D& seed, int seed_slice,
                              const LiverParams& params, const LiverProgress& progress)
{
    check_image(hu, "propagate_liver");
    check_seed(hu, seed, seed_slice);
    Context c{hu, params, progress, nullptr, nullptr, -1, {}, {}};
    const core::ImageF seed_img = core::axial_slice(hu, seed_slice);
    c.tissue = tissue_under(gaussian_smooth(seed_img, 1.0), on_grid(seed, seed_img.geometry()));
    LiverResult r = propagate(c, seed, seed_slice);
    r.stacked = r.mask;
    r.volume_ml = volume_ml(r.mask);
    return r;
}

LiverResult segment_head_up(const core::ImageF& hu, const LiverParams& params, const ShapeMemory* memory,
                            const LiverProgress& progress)
{
    check_image(hu, "segment_liver");
    if (hu.size[2] < params.min_slices)
        throw core::InvalidInputError("segment_liver: the volume has " + std::to_string(hu.size[2]) +
                                      " slices; the liver pipeline needs at least " + std::to_string(params.min_slices));
    using Named = std::pair<const char*, double>;
    const auto non_negative = [](std::initializer_list<Named> values) {
        for (const auto& [name, v] : values)
            if (!std::isfinite(v) || v < 0)
                throw core::InvalidInputError(std::string("segment_liver: ") + name + " must be finite and >= 0, is " +
                                              std::to_string(v));
    };
    non_negative({{"max_growth_per_mm", params.max_growth_per_mm},
                  {"growth_slack_mm", params.growth_slack_mm},
                  {"window_growth_per_mm", params.window_growth_per_mm},
                  {"window_margin_mm", params.window_margin_mm},
                  {"seed_window_mm", params.seed_window_mm},
                  {"seed_window_hold", params.seed_window_hold},
                  {"layer_clip_sigmas", params.layer_clip_sigmas}});
    if (params.use_edge_snap)
        (void)liver_snap_params(params, hu.spacing[0], hu.spacing[1]); // refuses a bad band or reference
    if (params.use_dome_contact)
        non_negative({{"contact_smoothing_mm", params.contact_smoothing_mm},
                      {"contact_sigmas", params.contact_sigmas},
                      {"contact_min_dip", params.contact_min_dip},
                      {"contact_closing_mm", params.contact_closing_mm},
                      {"contact_min_area_mm2", params.contact_min_area_mm2},
                      {"contact_heart_radius_mm", params.contact_heart_radius_mm}});
    if (params.fill_surface_lesions)
        check_surface_lesion_params(params.surface_lesions, "segment_liver: surface_lesions"); // before the work
    if (params.fill_vessel_inlets &&
        !(params.vessel_inlet_closing_mm > 0.0 && std::isfinite(params.vessel_inlet_closing_mm) &&
          params.vessel_inlet_sigmas >= 0.0 && std::isfinite(params.vessel_inlet_sigmas)))
        throw core::InvalidInputError("segment_liver: vessel_inlet_closing_mm must be finite and > 0 and "
                                      "vessel_inlet_sigmas finite and >= 0 (are " +
                                      std::to_string(params.vessel_inlet_closing_mm) + ", " +
                                      std::to_string(params.vessel_inlet_sigmas) + ")");
    if (params.use_heart_model &&
        !(params.heart_wall_mm >= 0.0 && std::isfinite(params.heart_wall_mm) && std::isfinite(params.heart_max_hu) &&
          params.heart_search_mm > 0.0 && std::isfinite(params.heart_search_mm) && params.heart_min_area_mm2 >= 0.0 &&
          std::isfinite(params.heart_min_area_mm2) && params.heart_min_area_fraction >= 0.0 &&
          params.heart_min_area_fraction <= 1.0))
        throw core::InvalidInputError("segment_liver: the heart model needs heart_wall_mm >= 0, heart_search_mm > 0, "
                                      "heart_min_area_mm2 >= 0, heart_min_area_fraction in [0, 1] and a finite "
                                      "heart_max_hu");
    if (!(params.wall_margin_mm >= 0.0 && std::isfinite(params.wall_margin_mm)))
        throw core::InvalidInputError("segment_liver: wall_margin_mm must be finite and >= 0, is " +
                                      std::to_string(params.wall_margin_mm));
    if (params.drop_growing_pieces && !(params.piece_growth_limit >= 1.0 && std::isfinite(params.piece_growth_limit)))
        throw core::InvalidInputError("segment_liver: piece_growth_limit must be finite and >= 1, is " +
                                      std::to_string(params.piece_growth_limit));
    if (params.keep_vessel_cut_pieces && !(params.vessel_cut_reach_mm > 0.0 && std::isfinite(params.vessel_cut_reach_mm)))
        throw core::InvalidInputError("segment_liver: vessel_cut_reach_mm must be finite and > 0, is " +
                                      std::to_string(params.vessel_cut_reach_mm));
    if (params.keep_vessel_cut_pieces)
        non_negative({{"vessel_cut_midline_reach_mm", params.vessel_cut_midline_reach_mm}});
    if (params.drop_growing_pieces && !(params.piece_lineage_limit >= 1.0 && std::isfinite(params.piece_lineage_limit)))
        throw core::InvalidInputError("segment_liver: piece_lineage_limit must be finite and >= 1, is " +
                                      std::to_string(params.piece_lineage_limit));
    if (params.use_tissue_stop && (!(params.tissue_stop_fraction > 0.0 && params.tissue_stop_fraction <= 1.0) ||
                                   !(params.tissue_stop_sigmas > 0.0) || !std::isfinite(params.tissue_stop_sigmas)))
        throw core::InvalidInputError(
            "segment_liver: tissue_stop_fraction must lie in (0, 1] and tissue_stop_sigmas be "
            "finite and > 0 (are " +
            std::to_string(params.tissue_stop_fraction) + ", " + std::to_string(params.tissue_stop_sigmas) + ")");
    if (params.use_tissue_stop && params.trim_at_tissue_stop &&
        (!(params.tissue_trim_keep > 0.0 && params.tissue_trim_keep <= 1.0) || params.tissue_trim_opening_px < 0 ||
         !(params.tissue_trim_min_area_fraction >= 0.0 && params.tissue_trim_min_area_fraction <= 1.0)))
        throw core::InvalidInputError("segment_liver: tissue_trim_keep and tissue_trim_min_area_fraction must lie in "
                                      "(0, 1] and [0, 1], tissue_trim_opening_px be >= 0 (are " +
                                      std::to_string(params.tissue_trim_keep) + ", " +
                                      std::to_string(params.tissue_trim_min_area_fraction) + ", " +
                                      std::to_string(params.tissue_trim_opening_px) + ")");
    const auto t0 = Clock::now();
    auto say = [&](const std::string& s) {
        if (progress)
            progress(s);
    };
    std::vector<std::pair<std::string, double>> timings;
    auto lap = [&](const std::string& name, Clock::time_point t) { timings.emplace_back(name, seconds_since(t)); };

    const Modality modality =
        params.modality == Modality::Auto ? detect_modality(hu, params.ct_air_fraction) : params.modality;
    const bool mr = modality == Modality::Mr;
    say(std::string(modality_name(modality)) + " volume" +
        (params.modality == Modality::Auto ? (mr ? " (no voxel reads as air in HU)" : " (air below -500 HU)") : ""));

    // The rib cage needs only the volume: it runs on a second thread beside the start slice and
    // the seed (both single-threaded), so that its time is mostly hidden.
    const bool use_ribs = params.use_rib_cage && !mr;
    double rib_seconds = 0.0;
    std::future<RibCageResult> rib_job;
    if (use_ribs)
        rib_job = std::async(std::launch::async, [&] {
            const auto tr = Clock::now();
            RibCageParams rp = params.ribs;
            rp.wall_width_mm = params.wall_margin_mm; // the wall margin's band, built with the ring
            RibCageResult rc = rib_cage(hu, rp);
            rib_seconds = seconds_since(tr);
            return rc;
        });

    auto t = Clock::now();
    StartSliceResult start;
    if (params.use_start_slice && !mr) {
        start = find_start_slice(hu, params.start);
        say(start.found ? "start slice " + std::to_string(start.slice) + " (heart and lungs), rotation " +
                              std::to_string(static_cast<int>(std::lround(start.rotation_deg))) + " deg"
                        : "no heart/lung slice: " + start.message);
    } else {
        start.message = mr ? "no start slice on MR (the heart template is a CT's)" : "start slice search switched off";
    }
    lap("start slice", t);

    // MR: the coil's shading is divided out first, so that one liver grey level holds across
    // the volume for the seed and the contrast map.
    BiasFieldResult bias;
    if (mr && params.mr.bias_correction) {
        t = Clock::now();
        bias = correct_bias_field(hu, params.mr.bias);
        lap("bias field", t);
        std::ostringstream s;
        s.precision(3);
        s << "bias field: gain " << bias.min_gain << " to " << bias.max_gain << " over the tissue, " << bias.iterations
          << " iterations" << (bias.converged ? "" : " (not converged)");
        say(s.str());
    }
    const core::ImageF& grey = bias.corrected.data.empty() ? hu : bias.corrected;

    t = Clock::now();
    LiverSeedParams seed_params = params.seed;
    if (mr) {
        // The MR's own units: the body and the plausible liver grey levels from its histogram.
        const double p99 = detail::sampled_quantile(grey, 0.99);
        if (!(p99 > 0.0))
            throw LiverNotFoundError("no liver found: read as MR, the volume has no signal (99th percentile " +
                                     std::to_string(p99) + ")");
        seed_params.body_threshold = params.mr.body_fraction * p99;
        seed_params.liver_range_lo = params.mr.liver_lo_fraction * p99;
        seed_params.liver_range_hi = params.mr.liver_hi_fraction * p99;
        seed_params.acceptance_sigma = params.mr.acceptance_sigma;
    }
    const LiverSeedResult seed = seed_liver(grey, start, seed_params);
    lap("seed", t);
    if (!seed.found)
        throw LiverNotFoundError("no liver found: " + seed.message);
    say("seed on slice " + std::to_string(seed.slice) + ": " + std::to_string(static_cast<int>(seed.area_mm2 / 100)) +
        " cm2, liver grey level " + std::to_string(static_cast<int>(std::lround(seed.liver_value))));

    // MR: from here on the pipeline sees the liver-contrast map, in which the liver reads as in a CT.
    core::ImageF mapped;
    if (mr) {
        t = Clock::now();
        mapped = mr_liver_contrast(grey, seed.liver_value, seed.liver_sigma, params.mr.noise_hu);
        lap("MR contrast map", t);
    }
    const core::ImageF& work = mr ? mapped : hu;

    t = Clock::now();
    RibCageResult ribs;
    if (use_ribs) {
        ribs = rib_job.get();
        const auto valid = std::count(ribs.valid.begin(), ribs.valid.end(), std::uint8_t(1));
        say("rib cage ring on " + std::to_string(valid) + " of " + std::to_string(hu.size[2]) + " slices");
        timings.emplace_back("rib cage (beside the start slice and seed)", rib_seconds);
    }
    lap("rib cage wait", t);

    Context c{work, params, progress, nullptr, nullptr, -1, {}, {}};
    c.ribs = use_ribs ? &ribs : nullptr;
    c.memory = params.use_shape_memory ? memory : nullptr;
    // The start slice shows the heart between both lungs above the liver's dome (thesis L4616):
    // the propagation upward ends below it.
    if (start.found && start.slice > seed.slice)
        c.top_slice = start.slice;
    if (start.found) {
        c.heart_known = true;
        c.heart_i = start.heart_centre[0];
        c.heart_j = start.heart_centre[1];
    }
    // The liver's grey level and spread on the smoothed image the layers are cut from, under
    // the seed (this patient, this scan).
    const core::ImageF seed_img = core::axial_slice(work, seed.slice);
    c.tissue = tissue_under(gaussian_smooth(seed_img, 1.0), on_grid(seed.mask, seed_img.geometry()));
    LiverResult r = propagate(c, seed.mask, seed.slice);
    // The ring and the inside served the propagation; only the wall is read from here on (two
    // byte volumes that would sit beside the 3-D pass, which sets the peak memory).
    ribs.inside = core::LabelImage3D();
    ribs.ring = core::LabelImage3D();
    for (const auto& tm : r.timings)
        timings.push_back(tm);
    r.stacked = r.mask;
    r.start = start;
    r.seed = seed;
    r.modality = modality;
    r.bias_corrected = !bias.corrected.data.empty();
    r.bias_min_gain = bias.min_gain;
    r.bias_max_gain = bias.max_gain;

    if (params.use_3d_pass) {
        t = Clock::now();
        r.mask = postprocess_liver(r.stacked, params.post);
        lap("3-D pass", t);
    }
    if (use_ribs && params.wall_margin_mm > 0) {
        // The wall margin: the diaphragm and intercostal layer under the ribs, which no edge
        // separates from the liver on a non-contrast or thick-slice scan (liver.md).
        t = Clock::now();
        for (std::size_t i = 0; i < r.mask.data.size(); ++i)
            if (ribs.wall.data[i] && r.mask.data[i]) {
                r.mask.data[i] = 0;
                ++r.wall_margin_voxels;
            }
        lap("wall margin", t);
        if (r.wall_margin_voxels > 0)
            say("wall margin: " + std::to_string(r.wall_margin_voxels) + " voxels within " +
                std::to_string(static_cast<int>(std::lround(params.wall_margin_mm))) + " mm of the ribs dropped");
    }
    r.volume_ml = volume_ml(r.mask);
    if (r.volume_ml <= 0)
        throw LiverNotFoundError("no liver found: the contour vanished");
    // first/last slices of the final mask
    const std::size_t plane = static_cast<std::size_t>(hu.size[0]) * static_cast<std::size_t>(hu.size[1]);
    r.first_slice = -1;
    for (int k = 0; k < hu.size[2]; ++k) {
        const auto b = r.mask.data.begin() + static_cast<std::ptrdiff_t>(plane * static_cast<std::size_t>(k));
        if (std::any_of(b, b + static_cast<std::ptrdiff_t>(plane), [](std::uint8_t v) { return v != 0; })) {
            if (r.first_slice < 0)
                r.first_slice = k;
            r.last_slice = k;
        }
    }
    timings.emplace_back("total", seconds_since(t0));
    r.timings = timings;
    return r;
}

//! Runs `run` on `hu` with its axes along the patient frame (core::patient_axis_order: LPS, +z to
//! the head) and maps everything the result says back to `hu`'s grid. The pipeline reads +k as
//! towards the head (the start slice above the liver, the upward propagation's heart model and
//! dome contact, the top slice); in plane it reads the anatomy through the direction cosines, but
//! a few choices still fall on the voxel grid (the seed search's cells are laid from voxel
//! (0, 0)), so the same scan stored with its rows or columns reversed (NIfTI's RAS against
//! DICOM's LPS) gave a slightly different liver. On the patient frame's grid every storage of
//! the same voxels gives the same one (liver.md, "Orientation"). A slice index in the result
//! counts along the input's axis that runs craniocaudally, from the input's first slice.
LiverResult canonical(const core::ImageF& hu, const char* who, const LiverProgress& progress,
                      const std::function<LiverResult(const core::ImageF&, const core::AxisOrder&)>& run)
{
    const core::AxisOrder order = core::patient_axis_order(hu);
    if (order.identity())
        return run(hu, order); // run checks the image
    check_image(hu, who); // before reordering it
    if (progress && !order.flips_only())
        progress("the slices are not axial: segmented on the volume's axial slices (slice numbers count along its "
                 "axis " + std::to_string(order.from[2]) + ", which runs along the body)");
    if (progress && order.flip[2])
        progress("the slices run from head to feet: segmented in reverse order (slice numbers in these messages "
                 "count from the last one)");
    LiverResult r = run(core::reorder_axes(hu, order), order);
    const core::AxisOrder back_order = order.inverse();
    const int nz = hu.size[std::size_t(order.from[2])];
    const auto back = [&](int k) { return k < 0 || !order.flip[2] ? k : nz - 1 - k; };
    if (!r.mask.data.empty())
        r.mask = core::reorder_axes(r.mask, back_order);
    if (!r.stacked.data.empty())
        r.stacked = core::reorder_axes(r.stacked, back_order);
    if (r.start.slice >= 0) {
        std::array<int, 3> canonical_size{};
        for (std::size_t a = 0; a < 3; ++a)
            canonical_size[a] = hu.size[std::size_t(order.from[a])];
        r.start.heart_centre = back_order.index_of(r.start.heart_centre, canonical_size);
    }
    r.start.slice = back(r.start.slice);
    if (order.flip[2])
        std::reverse(r.start.slice_scores.begin(), r.start.slice_scores.end());
    r.seed.slice = back(r.seed.slice);
    if (!r.seed.mask.data.empty() && order.from[2] == 2) {
        // The seed's pixels turned back; its one-slice grid is that slice of the input's. (On a
        // stack that is not axial the seed stays the axial slice it is, with that geometry.)
        core::LabelImage3D m = core::reorder_axes(r.seed.mask, back_order);
        const core::Vec3 o = hu.index_to_physical(0, 0, r.seed.slice);
        core::ImageGeometry g = hu.geometry();
        g.origin = {o.x, o.y, o.z};
        g.size[2] = 1;
        static_cast<core::ImageGeometry&>(m) = g;
        r.seed.mask = std::move(m);
    }
    r.seed_slice = back(r.seed_slice);
    if (order.flip[2]) {
        const int first = r.first_slice;
        r.first_slice = back(r.last_slice);
        r.last_slice = back(first);
        for (auto& s : r.slices)
            s.slice = back(s.slice);
        std::reverse(r.slices.begin(), r.slices.end());
    }
    return r;
}

} // namespace

LiverResult propagate_liver(const core::ImageF& hu, const core::LabelImage3D& seed, int seed_slice,
                            const LiverParams& params, const LiverProgress& progress)
{
    return canonical(hu, "propagate_liver", progress, [&](const core::ImageF& v, const core::AxisOrder& order) {
        if (order.identity())
            return propagate_head_up(v, seed, seed_slice, params, progress);
        if (!order.flips_only())
            throw core::InvalidInputError("propagate_liver: the volume's slices are not axial, so a seed slice of it "
                                          "is not an axial one (segment_liver takes any orientation)");
        check_seed(hu, seed, seed_slice); // before it is mapped, so that the messages name the input's
        return propagate_head_up(v, core::flip_axes(seed, {order.flip[0], order.flip[1], false}),
                                 order.flip[2] ? hu.size[2] - 1 - seed_slice : seed_slice, params, progress);
    });
}

LiverResult segment_liver(const core::ImageF& hu, const LiverParams& params, const ShapeMemory* memory,
                          const LiverProgress& progress)
{
    return canonical(hu, "segment_liver", progress, [&](const core::ImageF& v, const core::AxisOrder&) {
        return segment_head_up(v, params, memory, progress);
    });
}

} // namespace lobe::seg
