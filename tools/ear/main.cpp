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

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;
using PointWithNormal = std::pair<Point, Vector>;

int fail(int code, const std::string& message) {
    std::fprintf(stderr, "pumeta-ear: error: %s\n", message.c_str());
    return code;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 5 || std::string(argv[3]) != "--ratio")
        return fail(2, "usage: pumeta-ear INPUT.xyz OUTPUT.xyz --ratio R");
    const std::string input = argv[1], output = argv[2];
    const long ratio = std::strtol(argv[4], nullptr, 10);
    if (ratio < 2) return fail(2, std::string("--ratio must be an integer >= 2, found ") + argv[4]);

    std::ifstream in(input);
    if (!in) return fail(2, input + ": cannot open");
    std::vector<PointWithNormal> points;
    std::string line;
    for (long number = 1; std::getline(in, line); ++number) {
        std::istringstream fields(line);
        double x, y, z;
        if (!(fields >> x >> y >> z)) {
            if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
            return fail(2, input + ": line " + std::to_string(number) + ": expected x y z");
        }
        points.push_back({Point(x, y, z), Vector(0, 0, 0)});
    }
    if (points.size() < 20)
        return fail(
            2, input + ": " + std::to_string(points.size()) + " points; EAR needs at least 20");

    try {
        auto point_map = CGAL::First_of_pair_property_map<PointWithNormal>();
        auto normal_map = CGAL::Second_of_pair_property_map<PointWithNormal>();
        const auto params = CGAL::parameters::point_map(point_map).normal_map(normal_map);
        CGAL::jet_estimate_normals<CGAL::Sequential_tag>(points, 18, params);
        CGAL::mst_orient_normals(points, 18, params);
        const double spacing = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
            points, 6, CGAL::parameters::point_map(point_map));
        const std::size_t target = points.size() * static_cast<std::size_t>(ratio);
        CGAL::edge_aware_upsample_point_set<CGAL::Sequential_tag>(
            points, std::back_inserter(points),
            CGAL::parameters::point_map(point_map)
                .normal_map(normal_map)
                .sharpness_angle(25)
                .edge_sensitivity(0)
                .neighbor_radius(3 * spacing)
                .number_of_output_points(target));
    } catch (const std::exception& e) {
        return fail(1, std::string("CGAL failed: ") + e.what());
    }

    const std::string tmp = output + ".tmp";
    {
        std::ofstream out(tmp);
        out.precision(9);
        for (const auto& [p, n] : points) out << p.x() << " " << p.y() << " " << p.z() << "\n";
        if (!out) return fail(2, output + ": cannot write");
    }
    if (std::rename(tmp.c_str(), output.c_str()) != 0) return fail(2, output + ": cannot write");
    return 0;
}
