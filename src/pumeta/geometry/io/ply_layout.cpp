// Mapping a PLY header's elements onto a Geometry: vertex property targets and the face list.
#include "pumeta/core/error.h"
#include "pumeta/geometry/io/ply_format.h"

namespace pumeta::io::ply {

VertexLayout vertex_layout(const std::string& path, const Element& vertex) {
    const int xyz[3] = {vertex.find_scalar({"x"}), vertex.find_scalar({"y"}),
                        vertex.find_scalar({"z"})};
    const int normal[3] = {vertex.find_scalar({"nx"}), vertex.find_scalar({"ny"}),
                           vertex.find_scalar({"nz"})};
    const int color[3] = {vertex.find_scalar({"red", "diffuse_red"}),
                          vertex.find_scalar({"green", "diffuse_green"}),
                          vertex.find_scalar({"blue", "diffuse_blue"})};
    if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
        throw_input_error(path, "the 'vertex' element lacks an x, y or z property");
    VertexLayout layout;
    layout.target.assign(vertex.properties.size(), -1);
    layout.has_normals = normal[0] >= 0 && normal[1] >= 0 && normal[2] >= 0;
    layout.has_colors = color[0] >= 0 && color[1] >= 0 && color[2] >= 0;
    for (int axis = 0; axis < 3; ++axis) {
        layout.target[xyz[axis]] = axis;
        if (layout.has_normals) layout.target[normal[axis]] = 3 + axis;
        if (layout.has_colors) layout.target[color[axis]] = 6 + axis;
    }
    return layout;
}

FaceSource find_faces(const std::string& path, const Header& header) {
    for (size_t e = 0; e < header.elements.size(); ++e) {
        const Element& element = header.elements[e];
        if (element.name != "face") continue;
        const int list = element.find_list({"vertex_indices", "vertex_index"});
        if (list < 0) continue;
        if (is_float(element.properties[list].type))
            throw_input_error(path, "face property '{}' has a floating-point index type",
                              element.properties[list].name);
        return {static_cast<int>(e), list};
    }
    return {};
}

}  // namespace pumeta::io::ply
