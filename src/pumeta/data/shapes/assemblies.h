// Furniture-like and mechanical-like assemblies: unions of closed, outward primitive parts with
// random dimensions, each placed by a rigid transform. Parts may interpenetrate, so the result
// is a set of closed components rather than one closed surface. Furniture stands on z = 0 with
// z up, in metres; mechanical parts have sizes of about one unit.
//
// `detail` is the target tessellation edge length relative to the assembly's largest
// dimension (0.05 gives a few thousand triangles for a whole assembly).
#pragma once

#include <vector>

#include "pumeta/data/shapes/mesh.h"
#include "pumeta/data/shapes/random.h"

namespace pumeta::shapes {

/// Rectangular, round or oval top on four legs (square, round, tapered or turned) or on a
/// pedestal; optional apron, stretchers and lower shelf.
Mesh make_table(Rng& rng, double detail);
/// Seat on four legs with a solid or slatted back, optional arms and stretchers.
Mesh make_chair(Rng& rng, double detail);
/// Bookcase: side panels, top, bottom, shelves, optional back panel, plinth and dividers.
Mesh make_shelf(Rng& rng, double detail);
/// Cabinet body with doors and/or drawers carrying knobs or bar handles, on feet or a plinth.
Mesh make_cabinet(Rng& rng, double detail);
/// Desk or floor lamp: base, straight or jointed pole, open or closed shade, optional bulb.
Mesh make_lamp(Rng& rng, double detail);
/// Sofa of rounded boxes: base, back, optional arms, seat and back cushions, feet.
Mesh make_sofa(Rng& rng, double detail);

/// Spur gear with a bore, optional hub, shaft and a second stacked gear.
Mesh make_gear(Rng& rng, double detail);
/// Pipe flange with a neck, optional raised face and chamfer, bolts with hex heads and nuts.
Mesh make_flange(Rng& rng, double detail);
/// L or U bracket with optional fillet, gussets and bolt heads.
Mesh make_bracket(Rng& rng, double detail);
/// Stepped shaft with chamfered ends, optional collars with set screws and a key.
Mesh make_shaft(Rng& rng, double detail);
/// Pulley with hub, web and a grooved or flat rim, optional shaft.
Mesh make_pulley(Rng& rng, double detail);
/// Pillow-block bearing: base plate, pedestal, housing, bolts, optional shaft.
Mesh make_bearing_block(Rng& rng, double detail);

/// A random lathe profile from the pole (0, -height/2) to the pole (0, height/2) through
/// `knots` >= 2 points with radii in [min_fraction, 1] * max_radius, evenly spaced in z.
std::vector<Vec2> random_profile(Rng& rng, double height, double max_radius, int knots,
                                 double min_fraction);

}  // namespace pumeta::shapes
