// pumeta-mls: PCL's moving least squares upsampling (Alexa et al. 2003, the classical
// surface-fitting upsampler of robotics pipelines) as a separate program, so that PCL stays
// out of the pumeta library. Used by `pumeta eval --method external` and `pumeta reproduce`.
//
//   pumeta-mls INPUT.xyz OUTPUT.xyz --ratio R
//
// Each input point's neighbourhood within 3 times the input's average spacing (6 neighbours)
// gets PCL's degree-2 polynomial fit; PCL's random uniform density rule then places points on
// that fit around it, R per point at the median neighbour count (fewer where the input is
// denser, more where it is sparser), with a seeded generator. That yields about R·N points; a
// seeded random subset trims any excess to exactly R·N. Exit code 2 for bad input, 1 for a
// failure.
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/surface/mls.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/xyz.h"

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

constexpr const char* kProgram = "pumeta-mls";

/// Mean over the points of the mean distance to their k nearest other points.
double average_spacing(const Cloud::Ptr& cloud, int k) {
    pcl::KdTreeFLANN<pcl::PointXYZ> tree;
    tree.setInputCloud(cloud);
    std::vector<int> indices(k + 1);
    std::vector<float> sq(k + 1);
    double sum = 0;
    for (const auto& p : cloud->points) {
        const int found = tree.nearestKSearch(p, k + 1, indices, sq);
        double local = 0;
        for (int i = 1; i < found; ++i) local += std::sqrt(sq[i]);
        if (found > 1) sum += local / (found - 1);
    }
    return sum / static_cast<double>(cloud->size());
}

/// Median number of points within `radius` of each point (itself included).
double median_neighbours(const Cloud::Ptr& cloud, double radius) {
    pcl::KdTreeFLANN<pcl::PointXYZ> tree;
    tree.setInputCloud(cloud);
    std::vector<int> indices;
    std::vector<float> sq;
    std::vector<int> counts;
    counts.reserve(cloud->size());
    for (const auto& p : cloud->points) counts.push_back(tree.radiusSearch(p, radius, indices, sq));
    std::nth_element(counts.begin(), counts.begin() + counts.size() / 2, counts.end());
    return counts[counts.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    using namespace pumeta::tools;
    Arguments args;
    std::vector<Xyz> read;
    if (int code = load_input(argc, argv, kProgram, 20, "MLS", args, read)) return code;
    Cloud::Ptr cloud(new Cloud);
    for (const Xyz& p : read)
        cloud->push_back(pcl::PointXYZ(static_cast<float>(p[0]), static_cast<float>(p[1]),
                                       static_cast<float>(p[2])));

    // PCL's fit of each neighbourhood, then PCL's random uniform density rule: a point with n
    // neighbours in the radius gets floor(density / 2 / n) samples of its fit, drawn in the
    // square of side radius inside the disc of diameter radius, or its own projection when
    // that is 0. The rule runs here rather than in PCL, whose generator is seeded from
    // std::random_device, so that the same input gives the same output.
    std::vector<Eigen::Vector3d> fitted;
    try {
        const double spacing = average_spacing(cloud, 6);
        if (!(spacing > 0)) return fail(kProgram, 2, args.input + ": all points coincide");
        const double radius = 3 * spacing;
        pcl::MovingLeastSquares<pcl::PointXYZ, pcl::PointXYZ> mls;
        mls.setInputCloud(cloud);
        mls.setSearchMethod(
            pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
        mls.setSearchRadius(radius);
        mls.setPolynomialOrder(2);
        mls.setCacheMLSResults(true);
        Cloud smoothed;
        mls.process(smoothed);
        // R samples per point at the median neighbour count; the excess is trimmed below.
        const double density =
            std::ceil(2.0 * (args.ratio + 0.5) * median_neighbours(cloud, radius));
        const int coefficients =
            (mls.getPolynomialOrder() + 1) * (mls.getPolynomialOrder() + 2) / 2;
        std::mt19937_64 rng(0);
        std::uniform_real_distribution<double> offset(-radius / 2, radius / 2);
        for (const pcl::MLSResult& fit : mls.getMLSResults()) {
            if (!fit.valid || fit.num_neighbors <= 0) continue;
            const int samples = static_cast<int>(std::floor(density / 2 / fit.num_neighbors));
            if (samples <= 0) {
                fitted.push_back(
                    fit.projectQueryPoint(mls.getProjectionMethod(), coefficients).point);
                continue;
            }
            for (int added = 0; added < samples;) {
                const double u = offset(rng), v = offset(rng);
                if (u * u + v * v > radius * radius / 4) continue;
                // As PCL: the polynomial only where 5 neighbours per coefficient support it.
                fitted.push_back(fit.num_neighbors >= 5 * coefficients
                                     ? fit.projectPointSimpleToPolynomialSurface(u, v).point
                                     : fit.projectPointToMLSPlane(u, v).point);
                ++added;
            }
        }
    } catch (const std::exception& e) {
        return fail(kProgram, 1, std::string("PCL failed: ") + e.what());
    }
    // PCL reports some failures on stderr only, leaving no fits: not an empty output.
    if (fitted.empty()) return fail(kProgram, 1, "PCL produced no points");
    const std::size_t target = cloud->size() * static_cast<std::size_t>(args.ratio);
    std::vector<std::size_t> order(fitted.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    if (order.size() > target) {
        std::mt19937_64 rng(1);
        std::shuffle(order.begin(), order.end(), rng);
        order.resize(target);
        std::sort(order.begin(), order.end());
    }

    std::vector<Xyz> produced;
    produced.reserve(order.size());
    for (std::size_t i : order) produced.push_back({fitted[i].x(), fitted[i].y(), fitted[i].z()});
    if (auto error = write_xyz(args.output, produced)) return fail(kProgram, 2, *error);
    return 0;
}
