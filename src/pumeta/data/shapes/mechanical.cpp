// The mechanical-like assemblies of assemblies.h.
#include <algorithm>
#include <cmath>

#include "pumeta/data/shapes/assemblies.h"
#include "pumeta/data/shapes/primitives.h"

namespace pumeta::shapes {

namespace {

Mesh hex_prism(double radius, double height, const Tessellation& tess) {
    return extrude(regular_polygon(6, radius), height, tess);
}

/// A bolt head standing on a surface: a hex prism or a round cap, axis along +z, its base at
/// z = 0 (sunk slightly so that it meets the surface).
Mesh bolt_head(bool hex, double radius, double height, const Tessellation& tess) {
    Mesh head =
        hex ? hex_prism(radius, height, tess) : frustum(radius, 0.85 * radius, height, tess);
    return translated(head, {0, 0, height / 2 - 0.05 * height});
}

/// Appends the `steps` + 1 points of an arc of `radius` about `centre` from angle `from` to
/// angle `to` (an inner corner's fillet).
void add_arc(std::vector<Vec2>& polygon, Vec2 centre, double radius, double from, double to,
             int steps) {
    for (int k = 0; k <= steps; ++k) {
        double angle = from + (to - from) * k / steps;
        polygon.push_back(
            {centre.x + radius * std::cos(angle), centre.y + radius * std::sin(angle)});
    }
}

}  // namespace

Mesh make_gear(Rng& rng, double detail) {
    int teeth = rng.integer(12, 48);
    double root = rng.uniform(0.5, 0.8);
    double pitch = 2 * M_PI * root / teeth;
    double tip = root + pitch * rng.uniform(0.35, 0.6);
    double thickness = root * rng.uniform(0.1, 0.35);
    double bore = root * rng.uniform(0.12, 0.3);
    Tessellation tess{detail * 2 * tip};
    Mesh mesh;
    auto add_gear = [&](int n, double r_root, double r_tip, double t, double z) {
        std::vector<Vec2> outline = gear_outline(n, r_root, r_tip);
        mesh.append(
            translated(extrude_ring(outline, circle_at_angles(outline, bore), t, tess), {0, 0, z}));
    };
    add_gear(teeth, root, tip, thickness, 0);
    double top = thickness / 2;
    if (rng.chance(0.3)) {
        // A smaller gear of the same tooth pitch stacked on top.
        int small_teeth = std::max(8, static_cast<int>(teeth * rng.uniform(0.4, 0.7)));
        double small_root = root * small_teeth / teeth;
        double small_thickness = thickness * rng.uniform(0.8, 1.5);
        add_gear(small_teeth, small_root, small_root + (tip - root), small_thickness,
                 top + small_thickness / 2);
        top += small_thickness;
    }
    double extent = top;
    if (rng.chance(0.7)) {
        double hub = std::min(bore * rng.uniform(1.6, 2.4), 0.8 * root);
        double hub_height = thickness * rng.uniform(1.4, 2.5);
        mesh.append(translated(tube(bore, hub, hub_height, tess),
                               {0, 0, -thickness / 2 + 0.3 * thickness}));
        extent = std::max(extent, hub_height);
    }
    if (rng.chance(0.5)) {
        double length = 2 * extent * rng.uniform(1.5, 3.0);
        mesh.append(frustum(0.97 * bore, 0.97 * bore, length, tess));
    }
    return mesh;
}

Mesh make_flange(Rng& rng, double detail) {
    double outer = rng.uniform(0.5, 0.8), bore = outer * rng.uniform(0.2, 0.35);
    double neck = bore * rng.uniform(1.25, 1.6);
    double t = outer * rng.uniform(0.12, 0.25), neck_height = outer * rng.uniform(0.3, 0.8);
    Tessellation tess{detail * 2 * outer};
    int bolts = outer > 0.65 ? 2 * rng.integer(3, 6) : 2 * rng.integer(2, 4);
    double bolt_circle = (neck + outer) / 2;
    double head =
        std::min(0.4 * M_PI * bolt_circle / bolts, 0.35 * (outer - neck)) * rng.uniform(0.8, 1.0);
    double raised = rng.chance(0.4) ? t * rng.uniform(0.1, 0.3) : 0;
    double chamfer = rng.chance(0.5) ? t * rng.uniform(0.1, 0.3) : 0;

    // Profile counter-clockwise in (r, z): out along the bottom (with the raised face), up the
    // rim (chamfered), in along the top to the neck, up the neck, down the bore.
    std::vector<Vec2> loop{{bore, -raised}};
    if (raised > 0) {
        double face = neck + (bolt_circle - head - neck) * rng.uniform(0.3, 0.9);
        loop.push_back({face, -raised});
        loop.push_back({face, 0});
    }
    if (chamfer > 0) {
        loop.insert(
            loop.end(),
            {{outer - chamfer, 0}, {outer, chamfer}, {outer, t - chamfer}, {outer - chamfer, t}});
    } else {
        loop.insert(loop.end(), {{outer, 0}, {outer, t}});
    }
    loop.insert(loop.end(), {{neck, t}, {neck, t + neck_height}, {bore, t + neck_height}});
    Mesh mesh = lathe_loop(refine_polyline(loop, 2 * tess.edge, true), tess.around(outer));

    bool hex = rng.chance(0.7);
    double head_height = head * rng.uniform(0.5, 0.8), nut_height = head_height;
    double shank = 0.55 * head;
    Mesh top_head = translated(bolt_head(hex, head, head_height, tess), {0, 0, t});
    Mesh nut =
        translated(hex_prism(head, nut_height, tess), {0, 0, -nut_height / 2 + 0.05 * nut_height});
    // The shank runs from just below the nut into the head.
    Mesh bolt = rod({0, 0, -nut_height - 0.5 * shank}, {0, 0, t + 0.5 * head_height}, shank, tess);
    for (int k = 0; k < bolts; ++k) {
        double angle = 2 * M_PI * (k + 0.5) / bolts;
        Vec3 at{bolt_circle * std::cos(angle), bolt_circle * std::sin(angle), 0};
        Mat3 turn = rotation({0, 0, 1}, angle);
        mesh.append(transformed(top_head, turn, at));
        mesh.append(transformed(nut, turn, at));
        mesh.append(translated(bolt, at));
    }
    return mesh;
}

Mesh make_bracket(Rng& rng, double detail) {
    double a = rng.uniform(0.6, 1.2), b = rng.uniform(0.5, 1.2), th = rng.uniform(0.06, 0.15);
    double width = rng.uniform(0.4, 1.0);
    bool channel = rng.chance(0.3);
    Tessellation tess{detail * std::max({a, b, width})};
    double room = std::min(channel ? (a - 2 * th) / 2 : a - th, b - th);
    double fillet = rng.chance(0.6) ? std::min(th * rng.uniform(0.5, 2.0), 0.4 * room) : 0;
    int arc_steps = fillet > 0 ? std::max(3, tess.around(fillet) / 4) : 0;

    // Profile in the xz plane (counter-clockwise as (x, z)); inner corners optionally filleted.
    std::vector<Vec2> profile{{0, 0}, {a, 0}};
    if (channel) {
        profile.insert(profile.end(), {{a, b}, {a - th, b}});
        if (fillet > 0)
            add_arc(profile, {a - th - fillet, th + fillet}, fillet, 0, -M_PI / 2, arc_steps);
        else
            profile.push_back({a - th, th});
    } else {
        profile.push_back({a, th});
    }
    if (fillet > 0)
        add_arc(profile, {th + fillet, th + fillet}, fillet, 1.5 * M_PI, M_PI, arc_steps);
    else
        profile.push_back({th, th});
    profile.insert(profile.end(), {{th, b}, {0, b}});

    // Extruded along z, then turned so that the profile's second coordinate is up (+z) and the
    // extrusion runs along y.
    Mat3 stand = rotation({1, 0, 0}, M_PI / 2);
    Mesh mesh = transformed(extrude(refine_polyline(profile, 2 * tess.edge, true), width, tess),
                            stand, {0, 0, 0});
    if (!channel && rng.chance(0.6)) {
        double size = std::min(a, b) * rng.uniform(0.3, 0.6);
        double plate = rng.uniform(0.03, 0.08);
        Mesh gusset = extrude({{th, th}, {th + size, th}, {th, th + size}}, plate, tess);
        int count = rng.integer(1, 2);
        for (int k = 0; k < count; ++k) {
            double y = count == 1 ? 0 : (k == 0 ? -0.3 : 0.3) * width;
            mesh.append(transformed(gusset, stand, {0, y, 0}));
        }
    }
    bool hex = rng.chance(0.5);
    double head = std::min({0.15 * width, 0.25 * (a - th - fillet), 0.25 * (b - th - fillet)}) *
                  rng.uniform(0.6, 1.0);
    Mesh bolt = bolt_head(hex, head, 0.6 * head, tess);
    int rows = width > 0.6 ? 2 : 1;
    for (int k = 0; k < rows; ++k) {
        double y = rows == 1 ? 0 : (k == 0 ? -0.25 : 0.25) * width;
        double x = channel ? a / 2 : th + fillet + (a - th - fillet) * 0.6;
        mesh.append(translated(bolt, {x, y, th}));
        if (!channel) {
            double z = th + fillet + (b - th - fillet) * 0.6;
            mesh.append(transformed(bolt, rotation_from_z({1, 0, 0}), {th, y, z}));
        }
    }
    return mesh;
}

Mesh make_shaft(Rng& rng, double detail) {
    double length = rng.uniform(1.2, 2.0);
    int steps = rng.integer(2, 5);
    Tessellation tess{detail * length};
    std::vector<double> radii, bounds{-length / 2};
    for (int k = 0; k < steps; ++k) radii.push_back(rng.uniform(0.05, 0.15));
    for (int k = 1; k < steps; ++k)
        bounds.push_back(-length / 2 + length * (k + rng.uniform(-0.3, 0.3)) / steps);
    bounds.push_back(length / 2);

    double c0 = std::min(0.3 * radii.front(), 0.02), c1 = std::min(0.3 * radii.back(), 0.02);
    std::vector<Vec2> profile{
        {0, -length / 2}, {radii.front() - c0, -length / 2}, {radii.front(), -length / 2 + c0}};
    for (int k = 0; k + 1 < steps; ++k) {
        profile.push_back({radii[k], bounds[k + 1]});
        profile.push_back({radii[k + 1], bounds[k + 1]});
    }
    profile.insert(
        profile.end(),
        {{radii.back(), length / 2 - c1}, {radii.back() - c1, length / 2}, {0, length / 2}});
    double widest = *std::max_element(radii.begin(), radii.end());
    Mesh mesh = lathe(refine_polyline(profile, 2 * tess.edge, false), tess.around(widest));

    int collars = rng.integer(0, 2);
    for (int c = 0; c < collars; ++c) {
        int k = rng.integer(0, steps - 1);
        double w = rng.uniform(0.04, 0.1);
        if (bounds[k + 1] - bounds[k] < 3 * w) continue;
        double z = rng.uniform(bounds[k] + w, bounds[k + 1] - w);
        double outer = radii[k] * rng.uniform(1.4, 2.0);
        // The collar's bore is smaller than the shaft so that the two overlap rather than
        // share a surface.
        mesh.append(translated(tube(0.9 * radii[k], outer, w, tess), {0, 0, z}));
        mesh.append(rod({outer - 0.01, 0, z}, {outer + 0.25 * w, 0, z}, 0.2 * w, tess));
    }
    if (rng.chance(0.5)) {
        int k = static_cast<int>(std::max_element(radii.begin(), radii.end()) - radii.begin());
        double r = radii[k], span = bounds[k + 1] - bounds[k];
        double mid = (bounds[k] + bounds[k + 1]) / 2;
        mesh.append(block({0.75 * r, -0.25 * r, mid - span / 4},
                          {1.2 * r, 0.25 * r, mid + span / 4}, 0.05 * r, tess));
    }
    return mesh;
}

Mesh make_pulley(Rng& rng, double detail) {
    double outer = rng.uniform(0.4, 0.8), width = outer * rng.uniform(0.2, 0.45);
    int grooves = rng.integer(0, 3);
    double depth = grooves > 0 ? outer * rng.uniform(0.05, 0.1) : 0;
    double rim = outer - depth - outer * rng.uniform(0.05, 0.1);
    double bore = outer * rng.uniform(0.06, 0.12), hub = bore * rng.uniform(1.8, 2.6);
    double hub_width = width * rng.uniform(1.0, 1.5), web = width * rng.uniform(0.2, 0.5);
    Tessellation tess{detail * 2 * outer};

    // Counter-clockwise in (r, z): out under the hub, web and rim, up the grooved rim, back in.
    std::vector<Vec2> loop{{bore, -hub_width / 2}, {hub, -hub_width / 2}, {hub, -web / 2},
                           {rim, -web / 2},        {rim, -width / 2},     {outer, -width / 2}};
    for (int g = 0; g < grooves; ++g) {
        double z0 = -width / 2 + width * g / grooves;
        double z1 = g + 1 == grooves ? width / 2 : -width / 2 + width * (g + 1) / grooves;
        loop.insert(loop.end(), {{outer - depth, z0 + 0.4 * (z1 - z0)},
                                 {outer - depth, z0 + 0.6 * (z1 - z0)},
                                 {outer, z1}});
    }
    if (grooves == 0) loop.push_back({outer, width / 2});
    loop.insert(loop.end(), {{rim, width / 2},
                             {rim, web / 2},
                             {hub, web / 2},
                             {hub, hub_width / 2},
                             {bore, hub_width / 2}});
    Mesh mesh = lathe_loop(refine_polyline(loop, 2 * tess.edge, true), tess.around(outer));
    if (rng.chance(0.4)) {
        double length = hub_width * rng.uniform(1.5, 3.0);
        mesh.append(frustum(0.97 * bore, 0.97 * bore, length, tess));
    }
    return mesh;
}

Mesh make_bearing_block(Rng& rng, double detail) {
    double housing = rng.uniform(0.2, 0.35), bore = housing * rng.uniform(0.45, 0.65);
    double length = housing * rng.uniform(3.0, 4.5), base_width = rng.uniform(0.25, 0.4);
    double base = rng.uniform(0.05, 0.12);
    double centre = base + housing * rng.uniform(0.9, 1.4);
    double housing_width = base_width * rng.uniform(0.8, 1.1);
    Tessellation tess{detail * length};
    Mesh mesh;
    mesh.append(block({-length / 2, -base_width / 2, 0}, {length / 2, base_width / 2, base},
                      base * rng.uniform(0.0, 0.3), tess));
    double pedestal = housing * rng.uniform(0.8, 1.0);
    mesh.append(block({-pedestal, -0.45 * housing_width, 0.5 * base},
                      {pedestal, 0.45 * housing_width, centre}, 0.1 * base, tess));
    // The shaft runs across the base (along y).
    mesh.append(placed(tube(bore, housing, housing_width, tess), {0, 0, centre}, {0, 1, 0}));
    double head = std::min(0.3 * base_width, 0.15 * (length / 2 - pedestal)) * 0.8;
    Mesh bolt = bolt_head(rng.chance(0.7), head, 0.6 * head, tess);
    double x = (pedestal + length / 2) / 2;
    for (double s : {-1.0, 1.0}) mesh.append(translated(bolt, {s * x, 0, base}));
    if (rng.chance(0.5)) {
        // Grease nipple on top of the housing.
        double r = 0.08 * housing;
        mesh.append(rod({0, 0, centre + 0.9 * housing}, {0, 0, centre + 1.25 * housing}, r, tess));
        mesh.append(translated(uv_sphere(1.4 * r, tess), {0, 0, centre + 1.25 * housing}));
    }
    if (rng.chance(0.6)) {
        double half = housing_width * rng.uniform(0.8, 1.5);
        mesh.append(rod({0, -half, centre}, {0, half, centre}, 0.97 * bore, tess));
    }
    return mesh;
}

}  // namespace pumeta::shapes
