// Distance transforms against brute force on small random images, and the signed distance's
// half-voxel convention.
#include "lobe/seg/distance_transform.h"

#include "common/expect_error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <vector>

using namespace lobe;

namespace {

core::ImageGeometry grid(int nx, int ny, int nz, double hx, double hy, double hz)
{
    core::ImageGeometry g;
    g.size = {nx, ny, nz};
    g.spacing = {hx, hy, hz};
    g.origin = {-3.0, 7.5, 100.0};
    return g;
}

// Each voxel non-zero with probability p.
core::LabelImage3D random_mask(const core::ImageGeometry& g, double p, unsigned seed)
{
    core::LabelImage3D m(g, 0);
    std::mt19937 rng(seed);
    std::bernoulli_distribution on(p);
    for (auto& v : m.data)
        v = on(rng) ? static_cast<std::uint8_t>(1 + rng() % 255) : 0;
    return m;
}

// Exact distance [mm] from every voxel centre to the nearest non-zero voxel centre, O(n^2).
std::vector<double> brute_euclidean(const core::LabelImage3D& f)
{
    std::vector<double> d(f.data.size(), std::numeric_limits<double>::infinity());
    for (int k = 0; k < f.size[2]; ++k)
        for (int j = 0; j < f.size[1]; ++j)
            for (int i = 0; i < f.size[0]; ++i)
                for (int c = 0; c < f.size[2]; ++c)
                    for (int b = 0; b < f.size[1]; ++b)
                        for (int a = 0; a < f.size[0]; ++a) {
                            if (!f.at(a, b, c))
                                continue;
                            const double dx = (i - a) * f.spacing[0], dy = (j - b) * f.spacing[1],
                                         dz = (k - c) * f.spacing[2];
                            double& v = d[f.index(i, j, k)];
                            v = std::min(v, std::sqrt(dx * dx + dy * dy + dz * dz));
                        }
    return d;
}

std::vector<int> brute_chessboard(const core::LabelImage3D& f)
{
    std::vector<int> d(f.data.size(), -1);
    for (int k = 0; k < f.size[2]; ++k)
        for (int j = 0; j < f.size[1]; ++j)
            for (int i = 0; i < f.size[0]; ++i)
                for (int c = 0; c < f.size[2]; ++c)
                    for (int b = 0; b < f.size[1]; ++b)
                        for (int a = 0; a < f.size[0]; ++a) {
                            if (!f.at(a, b, c))
                                continue;
                            const int v = std::max({std::abs(i - a), std::abs(j - b), std::abs(k - c)});
                            int& best = d[f.index(i, j, k)];
                            if (best < 0 || v < best)
                                best = v;
                        }
    return d;
}

// The signed distance's definition, by brute force: from each voxel centre to the nearest box
// (the voxel's spacing around its centre) of a voxel of the other class, where the space
// outside the grid is outside (except along an axis one voxel long: a 2-D image has no z faces);
// negative inside.
std::vector<double> brute_signed(const core::LabelImage3D& m)
{
    const auto gap = [](int d, double h) { return std::max(0.0, (std::abs(d) - 0.5) * h); };
    std::vector<double> phi(m.data.size());
    for (int k = 0; k < m.size[2]; ++k)
        for (int j = 0; j < m.size[1]; ++j)
            for (int i = 0; i < m.size[0]; ++i) {
                const bool in = m.at(i, j, k) != 0;
                double best = std::numeric_limits<double>::infinity();
                if (in) // the grid's faces, along the axes the image extends along
                    for (int a = 0; a < 3; ++a) {
                        if (m.size[a] == 1)
                            continue;
                        const int p = a == 0 ? i : a == 1 ? j : k;
                        best = std::min({best, (p + 0.5) * m.spacing[a], (m.size[a] - p - 0.5) * m.spacing[a]});
                    }
                for (int c = 0; c < m.size[2]; ++c)
                    for (int b = 0; b < m.size[1]; ++b)
                        for (int a = 0; a < m.size[0]; ++a) {
                            if ((m.at(a, b, c) != 0) == in)
                                continue;
                            const double gx = gap(i - a, m.spacing[0]), gy = gap(j - b, m.spacing[1]),
                                         gz = gap(k - c, m.spacing[2]);
                            best = std::min(best, std::sqrt(gx * gx + gy * gy + gz * gz));
                        }
                phi[m.index(i, j, k)] = in ? -best : best;
            }
    return phi;
}

struct Case {
    int nx, ny, nz;
    double hx, hy, hz;
    double density;
};

// 2-D and 3-D, isotropic and strongly anisotropic, dense and very sparse (a sparse image has
// long lower envelopes and lines without any feature).
const Case kCases[] = {
    {23, 17, 1, 0.7, 1.3, 1.0, 0.05},  {31, 29, 1, 1.0, 1.0, 1.0, 0.002}, {40, 1, 1, 0.5, 1.0, 1.0, 0.1},
    {13, 11, 9, 0.6, 0.9, 2.5, 0.03},  {12, 12, 12, 1.0, 1.0, 1.0, 0.3},  {9, 14, 11, 2.0, 0.45, 0.8, 0.004},
    {1, 12, 10, 0.8, 1.1, 3.0, 0.05},
};

} // namespace

// Tolerance 1e-4 mm: both are exact; the transform only rounds squared distances (< 2000 mm^2
// here) to float, a relative error of 6e-8, i.e. under 1e-5 mm.
TEST(DistanceTransform, EuclideanMatchesBruteForce)
{
    unsigned seed = 1;
    for (const Case& c : kCases)
        for (int rep = 0; rep < 3; ++rep, ++seed) {
            const auto f = random_mask(grid(c.nx, c.ny, c.nz, c.hx, c.hy, c.hz), c.density, seed);
            const core::ImageF d = seg::euclidean_distance(f);
            ASSERT_TRUE(core::same_grid(d, f, 0.0));
            const auto expected = brute_euclidean(f);
            for (std::size_t i = 0; i < expected.size(); ++i) {
                if (std::isinf(expected[i]))
                    ASSERT_TRUE(std::isinf(d.data[i]) && d.data[i] > 0) << "voxel " << i << " seed " << seed;
                else
                    ASSERT_NEAR(d.data[i], expected[i], 1e-4) << "voxel " << i << " seed " << seed;
            }
        }
}

TEST(DistanceTransform, EuclideanWithoutFeatureIsInfiniteAndZeroOnFeatures)
{
    const auto g = grid(7, 5, 3, 1.0, 2.0, 3.0);
    const core::ImageF none = seg::euclidean_distance(core::LabelImage3D(g, 0));
    for (float v : none.data)
        EXPECT_TRUE(std::isinf(v) && v > 0);
    core::LabelImage3D one(g, 0);
    one.at(6, 4, 2) = 1;
    const core::ImageF d = seg::euclidean_distance(one);
    EXPECT_EQ(d.at(6, 4, 2), 0.f);
    // Exact for this one: sqrt(6^2 + 8^2 + 6^2) in mm, float rounding only (1e-5).
    EXPECT_NEAR(d.at(0, 0, 0), std::sqrt(36.0 + 64.0 + 36.0), 1e-5);
}

TEST(DistanceTransform, ChessboardMatchesBruteForce)
{
    unsigned seed = 100;
    for (const Case& c : kCases)
        for (int rep = 0; rep < 3; ++rep, ++seed) {
            const auto f = random_mask(grid(c.nx, c.ny, c.nz, c.hx, c.hy, c.hz), c.density, seed);
            const auto d = seg::chessboard_distance(f);
            ASSERT_TRUE(core::same_grid(d, f, 0.0));
            const auto expected = brute_chessboard(f);
            // Integers: exact equality.
            for (std::size_t i = 0; i < expected.size(); ++i)
                ASSERT_EQ(d.data[i], expected[i]) << "voxel " << i << " seed " << seed;
        }
}

TEST(DistanceTransform, ChessboardWithoutFeatureIsMinusOne)
{
    const auto d = seg::chessboard_distance(core::LabelImage3D(grid(6, 5, 4, 1, 1, 1), 0));
    for (int v : d.data)
        EXPECT_EQ(v, -1);
}

// Tolerance 1e-4 mm, as for the Euclidean transform: both sides are exact.
TEST(DistanceTransform, SignedMatchesBoxDistanceBruteForce)
{
    unsigned seed = 200;
    for (const Case& c : kCases)
        for (double density : {c.density, 0.5, 0.97})
            for (int rep = 0; rep < 2; ++rep, ++seed) {
                const auto m = random_mask(grid(c.nx, c.ny, c.nz, c.hx, c.hy, c.hz), density, seed);
                const core::ImageF phi = seg::signed_distance(m);
                ASSERT_TRUE(core::same_grid(phi, m, 0.0));
                const auto expected = brute_signed(m);
                for (std::size_t i = 0; i < expected.size(); ++i) {
                    if (std::isinf(expected[i]))
                        ASSERT_TRUE(std::isinf(phi.data[i]) && phi.data[i] > 0) << "voxel " << i;
                    else
                        ASSERT_NEAR(phi.data[i], expected[i], 1e-4) << "voxel " << i << " seed " << seed;
                }
            }
}

// The sign convention is exact: not a tolerance but an identity, on every voxel.
TEST(DistanceTransform, SignedIsNegativeExactlyOnTheMask)
{
    unsigned seed = 300;
    for (const Case& c : kCases)
        for (double density : {0.01, 0.2, 0.5, 0.9, 0.999}) {
            const auto m = random_mask(grid(c.nx, c.ny, c.nz, c.hx, c.hy, c.hz), density, ++seed);
            const core::ImageF phi = seg::signed_distance(m);
            for (std::size_t i = 0; i < m.data.size(); ++i) {
                ASSERT_EQ(phi.data[i] < 0, m.data[i] != 0) << "voxel " << i;
                ASSERT_NE(phi.data[i], 0.f); // the zero level lies between voxel centres
            }
        }
}

// One inside voxel: the zero level is its box, so the neighbour along axis a reads h_a / 2
// and the voxel itself -min(h) / 2, exactly (float rounding only, 1e-6).
TEST(DistanceTransform, SignedZeroLevelIsHalfAVoxelOutside)
{
    core::LabelImage3D m(grid(7, 7, 7, 0.7, 0.9, 2.5), 0);
    m.at(3, 3, 3) = 1;
    const core::ImageF phi = seg::signed_distance(m);
    EXPECT_NEAR(phi.at(3, 3, 3), -0.35, 1e-6);
    EXPECT_NEAR(phi.at(4, 3, 3), 0.35, 1e-6);
    EXPECT_NEAR(phi.at(2, 3, 3), 0.35, 1e-6);
    EXPECT_NEAR(phi.at(3, 4, 3), 0.45, 1e-6);
    EXPECT_NEAR(phi.at(3, 3, 2), 1.25, 1e-6);
    EXPECT_NEAR(phi.at(3, 3, 5), 1.25 + 2.5, 1e-6);
    // Diagonal neighbour: distance to the box corner.
    EXPECT_NEAR(phi.at(4, 4, 4), std::sqrt(0.35 * 0.35 + 0.45 * 0.45 + 1.25 * 1.25), 1e-6);
}

// A sphere's voxelisation lies within half a voxel diagonal of the sphere, so the signed
// distance to it differs from |p - c| - R by at most that much.
TEST(DistanceTransform, SignedApproximatesTheSphereWithinHalfAVoxelDiagonal)
{
    const auto g = grid(48, 44, 20, 0.8, 0.8, 2.0);
    core::LabelImage3D m(g, 0);
    const double cx = 19.3, cy = 17.1, cz = 19.7, r = 12.0; // mm from voxel (0,0,0)
    const auto dist = [&](int i, int j, int k) {
        return std::sqrt(std::pow(i * 0.8 - cx, 2) + std::pow(j * 0.8 - cy, 2) + std::pow(k * 2.0 - cz, 2));
    };
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i)
                m.at(i, j, k) = dist(i, j, k) < r ? 1 : 0;
    const core::ImageF phi = seg::signed_distance(m);
    const double tol = 0.5 * std::sqrt(0.8 * 0.8 * 2 + 2.0 * 2.0) + 1e-5;
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i)
                ASSERT_NEAR(phi.at(i, j, k), dist(i, j, k) - r, tol) << i << "," << j << "," << k;
}

// Outside the grid is outside: a full mask is bounded by the grid's faces (exact, 1e-6), and an
// empty one has no zero level at all (+infinity).
TEST(DistanceTransform, SignedOfFullAndEmptyMasks)
{
    const auto g = grid(5, 6, 3, 1.0, 0.5, 2.0);
    const core::ImageF full = seg::signed_distance(core::LabelImage3D(g, 1));
    EXPECT_NEAR(full.at(0, 0, 0), -0.25, 1e-6);
    EXPECT_NEAR(full.at(2, 3, 1), -1.25, 1e-6); // 2.5 half-voxels of 0.5 mm from the y faces
    EXPECT_NEAR(full.at(2, 2, 1), -1.25, 1e-6);
    EXPECT_NEAR(full.at(2, 2, 0), -1.0, 1e-6); // the z face is 1 mm away
    const core::ImageF empty = seg::signed_distance(core::LabelImage3D(g, 0));
    for (float v : empty.data)
        EXPECT_TRUE(std::isinf(v) && v > 0);
}

// Images above the size where the transforms go multi-threaded (64 Ki voxels), checked against
// brute force at 300 random voxels each (all voxels would take O(n^2)). Tolerance 1e-4 mm, as
// above: both are exact.
TEST(DistanceTransform, LargeImagesMatchBruteForceAtSampledVoxels)
{
    // Distance from voxel (i,j,k) to the nearest box of an inside voxel (to_inside) or of an
    // outside voxel or the grid's faces (!to_inside).
    const auto box_distance = [](const core::LabelImage3D& m, int i, int j, int k, bool to_inside) {
        const auto gap = [](int d, double h) { return std::max(0.0, (std::abs(d) - 0.5) * h); };
        double best = std::numeric_limits<double>::infinity();
        if (!to_inside)
            for (int a = 0; a < 3; ++a) {
                if (m.size[a] == 1)
                    continue;
                const int p = a == 0 ? i : a == 1 ? j : k;
                best = std::min({best, (p + 0.5) * m.spacing[a], (m.size[a] - p - 0.5) * m.spacing[a]});
            }
        for (int c = 0; c < m.size[2]; ++c)
            for (int b = 0; b < m.size[1]; ++b)
                for (int a = 0; a < m.size[0]; ++a)
                    if ((m.at(a, b, c) != 0) == to_inside) {
                        const double gx = gap(i - a, m.spacing[0]), gy = gap(j - b, m.spacing[1]),
                                     gz = gap(k - c, m.spacing[2]);
                        best = std::min(best, std::sqrt(gx * gx + gy * gy + gz * gz));
                    }
        return best;
    };
    std::mt19937 rng(7);
    for (const auto& g : {grid(300, 260, 1, 0.7, 0.8, 1.0), grid(70, 64, 18, 0.8, 0.75, 2.5)}) {
        // A blob (long runs inside and outside) plus sparse specks.
        core::LabelImage3D m = random_mask(g, 0.002, 11);
        for (int k = 0; k < g.size[2]; ++k)
            for (int j = 0; j < g.size[1]; ++j)
                for (int i = 0; i < g.size[0]; ++i) {
                    const double x = (i - 0.4 * g.size[0]) / (0.3 * g.size[0]), y = (j - 0.5 * g.size[1]) / (0.25 * g.size[1]),
                                 z = g.size[2] > 1 ? (k - 0.5 * g.size[2]) / (0.3 * g.size[2]) : 0.0;
                    if (x * x + y * y + z * z < 1)
                        m.at(i, j, k) = 1;
                }
        const core::ImageF edt = seg::euclidean_distance(m);
        const core::ImageF phi = seg::signed_distance(m);
        for (int n = 0; n < 300; ++n) {
            const int i = static_cast<int>(rng() % static_cast<unsigned>(g.size[0]));
            const int j = static_cast<int>(rng() % static_cast<unsigned>(g.size[1]));
            const int k = static_cast<int>(rng() % static_cast<unsigned>(g.size[2]));
            const bool in = m.at(i, j, k) != 0;
            double centre = std::numeric_limits<double>::infinity();
            for (int c = 0; c < g.size[2]; ++c)
                for (int b = 0; b < g.size[1]; ++b)
                    for (int a = 0; a < g.size[0]; ++a)
                        if (m.at(a, b, c)) {
                            const double dx = (i - a) * g.spacing[0], dy = (j - b) * g.spacing[1],
                                         dz = (k - c) * g.spacing[2];
                            centre = std::min(centre, std::sqrt(dx * dx + dy * dy + dz * dz));
                        }
            ASSERT_NEAR(edt.at(i, j, k), centre, 1e-4) << i << "," << j << "," << k;
            const double expected = in ? -box_distance(m, i, j, k, false) : box_distance(m, i, j, k, true);
            ASSERT_NEAR(phi.at(i, j, k), expected, 1e-4) << i << "," << j << "," << k;
        }
    }
}

TEST(DistanceTransform, MalformedImageIsRejected)
{
    core::LabelImage3D bad(grid(4, 4, 4, 1, 1, 1), 0);
    bad.data.resize(10);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::euclidean_distance(bad), "euclidean_distance", "10 values");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::signed_distance(bad), "signed_distance");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::chessboard_distance(bad), "chessboard_distance");
}
