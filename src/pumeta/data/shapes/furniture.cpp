// The furniture-like assemblies of assemblies.h.
#include <algorithm>
#include <cmath>

#include "pumeta/data/shapes/assemblies.h"
#include "pumeta/data/shapes/primitives.h"

namespace pumeta::shapes {

namespace {

enum class LegStyle { kSquare, kRound, kTapered, kTurned };

LegStyle random_leg_style(Rng& rng) { return static_cast<LegStyle>(rng.integer(0, 3)); }

/// A vertical leg of half-width `size` centred at the origin; legs of one piece of furniture
/// are copies of one leg.
Mesh make_leg(Rng& rng, LegStyle style, double size, double length, const Tessellation& tess) {
    switch (style) {
        case LegStyle::kSquare:
            return rounded_box({size, size, length / 2}, size * rng.uniform(0.0, 0.5), tess);
        case LegStyle::kRound:
            return frustum(size, size, length, tess);
        case LegStyle::kTapered:
            // Narrower at the floor.
            return frustum(size * rng.uniform(0.45, 0.75), size, length, tess);
        case LegStyle::kTurned:
            break;
    }
    std::vector<Vec2> profile = random_profile(rng, length, size, rng.integer(4, 8), 0.55);
    return lathe(refine_polyline(profile, 2 * tess.edge, false), tess.around(size));
}

/// Rotation leaning +z towards +y by `angle` (chair and sofa backs).
Mat3 lean_back(double angle) { return rotation({1, 0, 0}, -angle); }

}  // namespace

std::vector<Vec2> random_profile(Rng& rng, double height, double max_radius, int knots,
                                 double min_fraction) {
    std::vector<Vec2> profile{{0, -height / 2}};
    for (int k = 0; k < knots; ++k) {
        double z = k + 1 == knots ? height / 2 : -height / 2 + height * k / (knots - 1);
        profile.push_back({max_radius * rng.uniform(min_fraction, 1.0), z});
    }
    profile.push_back({0, height / 2});
    return profile;
}

Mesh make_table(Rng& rng, double detail) {
    enum { kRectangle, kRound, kOval };
    int top_shape = rng.integer(kRectangle, kOval);
    double width = rng.uniform(0.8, 1.8);
    double depth = top_shape == kRound ? width : width * rng.uniform(0.45, 0.85);
    double height = rng.uniform(0.4, 0.8);
    double thickness = rng.uniform(0.025, 0.06);
    Tessellation tess{detail * std::max(width, height)};
    Mesh mesh;
    if (top_shape == kRectangle) {
        mesh.append(block({-width / 2, -depth / 2, height - thickness},
                          {width / 2, depth / 2, height}, thickness * rng.uniform(0.0, 0.45),
                          tess));
    } else {
        Mesh top = frustum(width / 2, width / 2, thickness, tess);
        if (top_shape == kOval) top = scaled(std::move(top), {1, depth / width, 1});
        mesh.append(placed(std::move(top), {0, 0, height - thickness / 2}));
    }
    double under_top = height - thickness;
    if (top_shape != kRectangle && rng.chance(0.5)) {
        // Pedestal: a foot disc and a column.
        double foot_radius = std::min(width, depth) * rng.uniform(0.2, 0.35);
        double foot_height = rng.uniform(0.02, 0.05);
        mesh.append(
            placed(frustum(foot_radius, foot_radius * rng.uniform(0.3, 0.9), foot_height, tess),
                   {0, 0, foot_height / 2}));
        mesh.append(rod({0, 0, foot_height / 2}, {0, 0, under_top + thickness / 2},
                        rng.uniform(0.03, 0.07), tess));
        return mesh;
    }
    LegStyle style = random_leg_style(rng);
    double size = rng.uniform(0.02, 0.045);
    double inset = size + rng.uniform(0.02, 0.1);
    // Corners in the order (-,-), (+,-), (-,+), (+,+); on round tops inside the ellipse.
    double xi = top_shape == kRectangle ? width / 2 - inset : 0.3 * width;
    double yi = top_shape == kRectangle ? depth / 2 - inset : 0.3 * depth;
    std::array<Vec2, 4> corners{{{-xi, -yi}, {xi, -yi}, {-xi, yi}, {xi, yi}}};
    double leg_length = under_top + thickness / 2;  // legs end inside the top
    Mesh leg = make_leg(rng, style, size, leg_length, tess);
    for (Vec2 c : corners) mesh.append(translated(leg, {c.x, c.y, leg_length / 2}));

    if (top_shape == kRectangle && rng.chance(0.6)) {
        // Apron boards joining the legs under the top.
        double apron = rng.uniform(0.05, 0.1), board = 0.6 * size;
        double upper = under_top + thickness / 4;
        for (double s : {-1.0, 1.0}) {
            mesh.append(block({-xi, s * yi - board / 2, under_top - apron},
                              {xi, s * yi + board / 2, upper}, 0, tess));
            mesh.append(block({s * xi - board / 2, -yi, under_top - apron},
                              {s * xi + board / 2, yi, upper}, 0, tess));
        }
    }
    if (rng.chance(0.35)) {
        double z = height * rng.uniform(0.12, 0.3), radius = 0.4 * size;
        auto at = [&](int k) { return Vec3{corners[k].x, corners[k].y, z}; };
        for (auto [a, b] : {std::pair{0, 1}, {2, 3}, {0, 2}, {1, 3}})
            mesh.append(rod(at(a), at(b), radius, tess));
    } else if (top_shape == kRectangle && rng.chance(0.3)) {
        double z = height * rng.uniform(0.12, 0.3);
        mesh.append(block({-xi - size, -yi - size, z}, {xi + size, yi + size, z + 0.8 * thickness},
                          0, tess));
    }
    return mesh;
}

Mesh make_chair(Rng& rng, double detail) {
    double width = rng.uniform(0.4, 0.55), depth = rng.uniform(0.38, 0.5);
    double seat_height = rng.uniform(0.4, 0.48), seat_thickness = rng.uniform(0.03, 0.07);
    double back_height = rng.uniform(0.3, 0.5);
    Tessellation tess{detail * (seat_height + back_height)};
    Mesh mesh;
    mesh.append(block({-width / 2, -depth / 2, seat_height - seat_thickness},
                      {width / 2, depth / 2, seat_height}, seat_thickness * rng.uniform(0.0, 0.45),
                      tess));
    double size = rng.uniform(0.015, 0.028);
    double inset = size + rng.uniform(0.005, 0.03);
    double xi = width / 2 - inset, yi = depth / 2 - inset;
    double mid_seat = seat_height - seat_thickness / 2;
    Mesh leg = make_leg(rng, random_leg_style(rng), size, mid_seat, tess);
    for (double sx : {-1.0, 1.0})
        for (double sy : {-1.0, 1.0})
            mesh.append(translated(leg, {sx * xi, sy * yi, mid_seat / 2}));

    // The back leans towards +y (the chair faces -y), pivoting at the seat's back edge.
    double tilt = rng.uniform(0.0, 0.25);
    Mat3 lean = lean_back(tilt);
    Vec3 up = lean * Vec3{0, 0, 1};
    double rise = back_height + seat_thickness / 2;  // from mid-seat to the top of the back
    if (rng.chance(0.5)) {
        double t = rng.uniform(0.015, 0.04), panel_width = width * rng.uniform(0.75, 1.0);
        Mesh panel =
            rounded_box({panel_width / 2, t / 2, rise / 2}, t * rng.uniform(0.0, 0.45), tess);
        Vec3 pivot{0, depth / 2 - t / 2, mid_seat};
        mesh.append(transformed(std::move(panel), lean, pivot + up * (rise / 2)));
    } else {
        // Posts above the back legs, a top rail, and vertical slats or horizontal rails.
        double post = 0.8 * size;
        for (double sx : {-1.0, 1.0}) {
            Vec3 foot{sx * xi, yi, mid_seat};
            mesh.append(rod(foot, foot + up * rise, post, tess));
        }
        double rail = rng.uniform(0.04, 0.1);
        Vec3 base{0, yi, mid_seat};
        mesh.append(transformed(rounded_box({xi + post, post, rail / 2}, 0.5 * post, tess), lean,
                                base + up * (rise - rail / 2)));
        int slats = rng.integer(0, 4);
        double span = rise - rail - seat_thickness / 2;  // from the seat top to the rail
        if (rng.chance(0.5)) {
            for (int k = 0; k < slats; ++k) {
                double x = -xi + 2 * xi * (k + 1) / (slats + 1);
                double half_width = std::min(0.03, xi / (slats + 1) * 0.6);
                mesh.append(
                    transformed(rounded_box({half_width, 0.5 * post, span / 2}, 0, tess), lean,
                                base + Vec3{x, 0, 0} + up * (seat_thickness / 2 + span / 2)));
            }
        } else {
            for (int k = 0; k < std::min(slats, 3); ++k) {
                double along = seat_thickness / 2 + span * (k + 1) / (std::min(slats, 3) + 1);
                mesh.append(transformed(rounded_box({xi, 0.5 * post, 0.4 * rail / 2}, 0, tess),
                                        lean, base + up * along));
            }
        }
    }
    if (rng.chance(0.3)) {
        double arm_height = rng.uniform(0.18, 0.25), arm_width = rng.uniform(0.03, 0.06);
        for (double sx : {-1.0, 1.0}) {
            Vec3 front{sx * xi, -yi, seat_height};
            mesh.append(rod(front - Vec3{0, 0, seat_thickness / 2}, front + Vec3{0, 0, arm_height},
                            0.8 * size, tess));
            mesh.append(block({sx * xi - arm_width / 2, -yi - 0.03, seat_height + arm_height},
                              {sx * xi + arm_width / 2, yi, seat_height + arm_height + 0.025}, 0.01,
                              tess));
        }
    }
    if (rng.chance(0.4)) {
        double z = seat_height * rng.uniform(0.15, 0.35), radius = 0.4 * size;
        for (double s : {-1.0, 1.0}) {
            mesh.append(rod({s * xi, -yi, z}, {s * xi, yi, z}, radius, tess));
            mesh.append(rod({-xi, s * yi, z}, {xi, s * yi, z}, radius, tess));
        }
    }
    return mesh;
}

Mesh make_shelf(Rng& rng, double detail) {
    double width = rng.uniform(0.5, 1.2), depth = rng.uniform(0.22, 0.4);
    double height = rng.uniform(0.6, 2.0), t = rng.uniform(0.015, 0.03);
    double plinth = rng.chance(0.5) ? rng.uniform(0.04, 0.1) : 0;
    Tessellation tess{detail * std::max(width, height)};
    double rounding = t * rng.uniform(0.0, 0.3);
    Mesh mesh;
    double xi = width / 2 - t;
    for (double s : {-1.0, 1.0})
        mesh.append(block({s < 0 ? -width / 2 : xi, -depth / 2, 0},
                          {s < 0 ? -xi : width / 2, depth / 2, height}, rounding, tess));
    if (rng.chance(0.4)) {
        double overhang = rng.uniform(0.01, 0.04);
        mesh.append(block({-width / 2 - overhang, -depth / 2 - overhang, height},
                          {width / 2 + overhang, depth / 2, height + t}, rounding, tess));
    } else {
        mesh.append(block({-xi, -depth / 2, height - t}, {xi, depth / 2, height}, rounding, tess));
    }
    mesh.append(block({-xi, -depth / 2, plinth}, {xi, depth / 2, plinth + t}, rounding, tess));
    if (plinth > 0)
        mesh.append(
            block({-xi, -depth / 2 + 0.02, 0}, {xi, -depth / 2 + 0.02 + t, plinth}, 0, tess));
    int compartments =
        std::max(1, static_cast<int>(std::lround((height - plinth) / rng.uniform(0.25, 0.4))));
    double setback = rng.uniform(0.0, 0.03);
    std::vector<double> levels{plinth + t};
    for (int k = 1; k < compartments; ++k) {
        double z = plinth + (height - plinth) * k / compartments;
        levels.push_back(z + t / 2);
        mesh.append(block({-xi, -depth / 2 + setback, z - t / 2}, {xi, depth / 2, z + t / 2},
                          rounding, tess));
    }
    levels.push_back(height - t);
    if (rng.chance(0.7)) {
        double back = rng.uniform(0.004, 0.01);
        mesh.append(
            block({-width / 2, depth / 2 - back, plinth}, {width / 2, depth / 2, height}, 0, tess));
    }
    if (rng.chance(0.3)) {
        // A vertical divider in one compartment.
        int k = rng.integer(0, compartments - 1);
        double x = xi * rng.uniform(-0.5, 0.5);
        double bottom = levels[k], top = k + 1 < compartments ? levels[k + 1] - t : levels[k + 1];
        mesh.append(
            block({x - t / 2, -depth / 2 + setback, bottom}, {x + t / 2, depth / 2, top}, 0, tess));
    }
    return mesh;
}

Mesh make_cabinet(Rng& rng, double detail) {
    double width = rng.uniform(0.4, 1.4), depth = rng.uniform(0.35, 0.6);
    double height = rng.uniform(0.45, 1.1);
    double foot = rng.chance(0.6) ? rng.uniform(0.04, 0.15) : 0;
    Tessellation tess{detail * std::max(width, height)};
    Mesh mesh;
    mesh.append(block({-width / 2, -depth / 2, foot}, {width / 2, depth / 2, height},
                      rng.uniform(0.0, 0.01), tess));
    if (rng.chance(0.5)) {
        double overhang = rng.uniform(0.01, 0.04), t = rng.uniform(0.02, 0.04);
        mesh.append(block({-width / 2 - overhang, -depth / 2 - overhang, height},
                          {width / 2 + overhang, depth / 2 + overhang, height + t},
                          t * rng.uniform(0.0, 0.45), tess));
    }
    if (foot > 0) {
        double size = rng.uniform(0.02, 0.04);
        Mesh leg = make_leg(rng, random_leg_style(rng), size, foot + 0.01, tess);
        for (double sx : {-1.0, 1.0})
            for (double sy : {-1.0, 1.0})
                mesh.append(translated(leg, {sx * (width / 2 - size - 0.02),
                                             sy * (depth / 2 - size - 0.02), (foot + 0.01) / 2}));
    }

    // Fronts: rectangles (x0, z0, x1, z1) on the face y = -depth/2.
    struct Front {
        double x0, z0, x1, z1;
        bool drawer;
    };
    double margin = rng.uniform(0.01, 0.03);
    double left = -width / 2 + margin, right = width / 2 - margin;
    double bottom = foot + margin, top = height - margin;
    std::vector<Front> fronts;
    auto add_row = [&](double z0, double z1, int columns, bool drawer) {
        for (int c = 0; c < columns; ++c)
            fronts.push_back({left + (right - left) * c / columns, z0,
                              left + (right - left) * (c + 1) / columns, z1, drawer});
    };
    switch (rng.integer(0, 2)) {
        case 0:
            add_row(bottom, top, rng.integer(1, 2), false);
            break;
        case 1: {
            int rows = rng.integer(2, 5), columns = rng.integer(1, 2);
            for (int r = 0; r < rows; ++r)
                add_row(bottom + (top - bottom) * r / rows,
                        bottom + (top - bottom) * (r + 1) / rows, columns, true);
            break;
        }
        default: {
            double split = top - (top - bottom) * rng.uniform(0.2, 0.35);
            add_row(split, top, rng.integer(1, 3), true);
            add_row(bottom, split, rng.integer(1, 2), false);
        }
    }
    double gap = 0.003, panel = rng.uniform(0.012, 0.02);
    double face = -depth / 2 - panel;
    bool knobs = rng.chance(0.5);
    double knob = rng.uniform(0.01, 0.02), bar = rng.uniform(0.005, 0.009);
    for (size_t i = 0; i < fronts.size(); ++i) {
        const Front& f = fronts[i];
        mesh.append(block({f.x0 + gap, face, f.z0 + gap},
                          {f.x1 - gap, -depth / 2 + 0.005, f.z1 - gap}, 0.003, tess));
        // Drawers are pulled in the middle, doors at the edge nearer the cabinet's centre.
        double cx = (f.x0 + f.x1) / 2, cz = (f.z0 + f.z1) / 2;
        double edge = std::min(0.06, 0.25 * (f.x1 - f.x0));
        if (!f.drawer) cx = cx < 0 ? f.x1 - edge : f.x0 + edge;
        if (knobs) {
            Vec3 centre{cx, face - 0.02, cz};
            mesh.append(rod(centre, {cx, face + 0.002, cz}, 0.4 * knob, tess));
            mesh.append(translated(uv_sphere(knob, tess), centre));
            continue;
        }
        double length = std::min(0.2, 0.6 * (f.drawer ? f.x1 - f.x0 : f.z1 - f.z0));
        Vec3 along = f.drawer ? Vec3{length / 2, 0, 0} : Vec3{0, 0, length / 2};
        Vec3 centre{cx, face - 0.03, cz};
        mesh.append(rod(centre - along, centre + along, bar, tess));
        for (double s : {-0.8, 0.8})
            mesh.append(
                rod(centre + along * s, centre + along * s + Vec3{0, 0.032, 0}, 0.8 * bar, tess));
    }
    return mesh;
}

Mesh make_lamp(Rng& rng, double detail) {
    bool floor_lamp = rng.chance(0.4);
    double height = floor_lamp ? rng.uniform(1.2, 1.8) : rng.uniform(0.35, 0.6);
    double scale = floor_lamp ? 1.6 : 1.0;
    Tessellation tess{detail * height};
    Mesh mesh;
    double base_radius = rng.uniform(0.07, 0.12) * scale;
    double base_height = rng.uniform(0.015, 0.04) * scale;
    switch (rng.integer(0, 2)) {
        case 0:
            mesh.append(
                placed(frustum(base_radius, base_radius * rng.uniform(0.6, 1.0), base_height, tess),
                       {0, 0, base_height / 2}));
            break;
        case 1: {
            // A dome: a quarter ellipse from the rim up to the axis.
            std::vector<Vec2> profile{{0, 0}};
            int steps = std::max(4, tess.around(base_radius) / 4);
            for (int k = 0; k < steps; ++k) {
                double angle = M_PI / 2 * k / steps;
                profile.push_back(
                    {base_radius * std::cos(angle), 2 * base_height * std::sin(angle)});
            }
            profile.push_back({0, 2 * base_height});
            mesh.append(
                lathe(refine_polyline(profile, 2 * tess.edge, false), tess.around(base_radius)));
            break;
        }
        default:
            mesh.append(block({-base_radius, -base_radius, 0},
                              {base_radius, base_radius, base_height}, 0.3 * base_height, tess));
    }
    double pole = rng.uniform(0.006, 0.012) * scale;
    Vec3 head;
    Vec3 shade_axis{0, 0, 1};
    if (rng.chance(0.6)) {
        head = {0, 0, height * rng.uniform(0.75, 0.85)};
        mesh.append(rod({0, 0, base_height / 2}, head, pole, tess));
    } else {
        Vec3 joint{0, 0, height * rng.uniform(0.45, 0.65)};
        mesh.append(rod({0, 0, base_height / 2}, joint, pole, tess));
        double angle = rng.uniform(0.3, 1.2), arm = height * rng.uniform(0.3, 0.45);
        head = joint + Vec3{std::sin(angle) * arm, 0, std::cos(angle) * arm};
        mesh.append(rod(joint, head, pole, tess));
        for (Vec3 p : {joint, head}) mesh.append(translated(uv_sphere(2 * pole, tess), p));
        double tilt = rng.uniform(0.3, 1.2);
        shade_axis = {std::sin(tilt), 0, std::cos(tilt)};
    }
    double shade_height = rng.uniform(0.12, 0.25) * scale;
    double bottom_radius = rng.uniform(0.08, 0.16) * scale;
    double top_radius = bottom_radius * rng.uniform(0.4, 0.9);
    double wall = rng.uniform(0.004, 0.01) * scale;
    // The shade's own +z points along shade_axis; its upper part holds the head.
    Vec3 centre = head - shade_axis * (0.3 * shade_height);
    Mesh shade;
    bool open = true;
    switch (rng.integer(0, 3)) {
        case 0: {
            double h = shade_height / 2;
            shade = lathe_loop({{bottom_radius - wall, -h},
                                {bottom_radius, -h},
                                {top_radius, h},
                                {top_radius - wall, h}},
                               tess.around(bottom_radius));
            break;
        }
        case 1:
            shade = frustum(bottom_radius, top_radius, shade_height, tess);
            open = false;
            break;
        case 2:
            shade = icosphere(bottom_radius, 3);
            open = false;
            break;
        default: {
            // A dome shell (half ellipsoid) with a hole at the top for the pole.
            double hole = 0.3 * bottom_radius;
            double top_angle = std::acos(hole / bottom_radius);
            int steps = std::max(4, tess.around(bottom_radius) / 4);
            std::vector<Vec2> loop;
            for (int k = 0; k <= steps; ++k) {
                double a = top_angle * k / steps;
                loop.push_back(
                    {bottom_radius * std::cos(a), shade_height * std::sin(a) - shade_height / 2});
            }
            for (int k = steps; k >= 0; --k) {
                double a = top_angle * k / steps;
                loop.push_back({(bottom_radius - wall) * std::cos(a),
                                (shade_height - wall) * std::sin(a) - shade_height / 2});
            }
            shade = lathe_loop(loop, tess.around(bottom_radius));
        }
    }
    mesh.append(placed(std::move(shade), centre, shade_axis));
    if (open && rng.chance(0.5)) mesh.append(translated(uv_sphere(0.5 * top_radius, tess), centre));
    return mesh;
}

Mesh make_sofa(Rng& rng, double detail) {
    double width = rng.uniform(1.2, 2.4), depth = rng.uniform(0.75, 1.0);
    double seat_height = rng.uniform(0.38, 0.46), arm_height = rng.uniform(0.55, 0.7);
    double back_height = rng.uniform(0.7, 0.95), feet = rng.uniform(0.03, 0.12);
    double soft = rng.uniform(0.02, 0.06);
    Tessellation tess{detail * width};
    double arm_width = rng.chance(0.85) ? rng.uniform(0.1, 0.22) : 0;
    double back_thickness = rng.uniform(0.12, 0.25);
    double cushion = rng.uniform(0.08, 0.15);
    Mesh mesh;
    mesh.append(block({-width / 2, -depth / 2, feet}, {width / 2, depth / 2, seat_height - cushion},
                      soft, tess));
    mesh.append(block({-width / 2, depth / 2 - back_thickness, feet},
                      {width / 2, depth / 2, back_height}, soft * rng.uniform(1.0, 2.0), tess));
    double xi = width / 2 - arm_width;
    if (arm_width > 0)
        for (double s : {-1.0, 1.0})
            mesh.append(block({s < 0 ? -width / 2 : xi, -depth / 2, feet},
                              {s < 0 ? -xi : width / 2, depth / 2, arm_height}, 1.5 * soft, tess));
    int seats = rng.integer(1, 3);
    double gap = 0.005;
    bool back_cushions = rng.chance(0.6);
    double back_cushion = rng.uniform(0.1, 0.18);
    Mat3 lean = lean_back(rng.uniform(0.05, 0.2));
    for (int k = 0; k < seats; ++k) {
        double x0 = -xi + 2 * xi * k / seats + gap, x1 = -xi + 2 * xi * (k + 1) / seats - gap;
        mesh.append(block({x0, -depth / 2 + 0.02, seat_height - cushion},
                          {x1, depth / 2 - back_thickness + 0.02, seat_height},
                          std::min(1.5 * soft, 0.45 * cushion), tess));
        if (!back_cushions) continue;
        double rise = 0.9 * (back_height - seat_height);
        Mesh pillow = rounded_box({(x1 - x0) / 2, back_cushion / 2, rise / 2},
                                  std::min(1.5 * soft, 0.45 * back_cushion), tess);
        Vec3 pivot{(x0 + x1) / 2, depth / 2 - back_thickness - back_cushion / 2 + 0.02,
                   seat_height};
        mesh.append(transformed(std::move(pillow), lean, pivot + lean * Vec3{0, 0, rise / 2}));
    }
    double foot_radius = rng.uniform(0.02, 0.04);
    Mesh leg = make_leg(rng, random_leg_style(rng), foot_radius, feet + 0.01, tess);
    int columns = width > 1.8 ? 3 : 2;
    for (int c = 0; c < columns; ++c)
        for (double sy : {-1.0, 1.0}) {
            double x = -(width / 2 - 0.06) + (width - 0.12) * c / (columns - 1);
            mesh.append(translated(leg, {x, sy * (depth / 2 - 0.06), (feet + 0.01) / 2}));
        }
    return mesh;
}

}  // namespace pumeta::shapes
