// pumeta-ear: CGAL's edge-aware upsampling (Huang et al. 2013, "EAR", the classical method
// the paper compares with) as a separate program, so that CGAL's GPL-3 point-set processing
// stays out of the pumeta library. Normals come from jet fitting, oriented by a minimum
// spanning tree. Used by `pumeta eval --method external` and `pumeta reproduce`.
//
//   pumeta-ear INPUT.xyz OUTPUT.xyz --ratio R
//
// The neighbourhood radius is 3 times the input's average spacing (6 neighbours), so the
// same settings work at any scale. EAR stops near, not exactly at, R·N points: the output
// holds what it produced. Exit code 2 for bad input, 1 for a failure.
#include <CGAL/Simple_cartesian.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/edge_aware_upsample_point_set.h>
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/mst_orient_normals.h>
#include <CGAL/property_map.h>

#include <string>
#include <utility>
#include <vector>

#include "common/xyz.h"

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;
using PointWithNormal = std::pair<Point, Vector>;
constexpr const char* kProgram = "pumeta-ear";

}  // namespace

int main(int argc, char** argv) {
    using namespace pumeta::tools;
    Arguments args;
    std::vector<Xyz> read;
    if (int code = load_input(argc, argv, kProgram, 20, "EAR", args, read)) return code;
    std::vector<PointWithNormal> points;
    points.reserve(read.size());
    for (const Xyz& p : read) points.push_back({Point(p[0], p[1], p[2]), Vector(0, 0, 0)});

    try {
        auto point_map = CGAL::First_of_pair_property_map<PointWithNormal>();
        auto normal_map = CGAL::Second_of_pair_property_map<PointWithNormal>();
        const auto params = CGAL::parameters::point_map(point_map).normal_map(normal_map);
        CGAL::jet_estimate_normals<CGAL::Sequential_tag>(points, 18, params);
        CGAL::mst_orient_normals(points, 18, params);
        const double spacing = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
            points, 6, CGAL::parameters::point_map(point_map));
        const std::size_t target = points.size() * static_cast<std::size_t>(args.ratio);
        CGAL::edge_aware_upsample_point_set<CGAL::Sequential_tag>(
            points, std::back_inserter(points),
            CGAL::parameters::point_map(point_map)
                .normal_map(normal_map)
                .sharpness_angle(25)
                .edge_sensitivity(0)
                .neighbor_radius(3 * spacing)
                .number_of_output_points(target));
    } catch (const std::exception& e) {
        return fail(kProgram, 1, std::string("CGAL failed: ") + e.what());
    }

    std::vector<Xyz> produced;
    produced.reserve(points.size());
    for (const auto& [p, n] : points) produced.push_back({p.x(), p.y(), p.z()});
    if (auto error = write_xyz(args.output, produced)) return fail(kProgram, 2, *error);
    return 0;
}
