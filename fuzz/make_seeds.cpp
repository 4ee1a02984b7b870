// Writes the fuzz targets' seed corpora: small files of every shape the readers accept,
// made by pumeta's own writers where it has one, byte by byte where it has none (STL, LAS),
// and tiny checkpoints of every backbone.
//   fuzz_make_seeds OUT_DIR   -> OUT_DIR/<target>/<seed files>
#include <ATen/ATen.h>
#include <caffe2/serialize/inline_container.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/checkpoint.h"

namespace fs = std::filesystem;
using namespace pumeta;

namespace {

void write_bytes(const fs::path& file, const std::string& bytes) {
    std::ofstream(file, std::ios::binary) << bytes;
}

template <class T>
void put(std::string& out, T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out.append(bytes, sizeof(T));
}

// Four points and a tetrahedron's four faces: the smallest mesh with every feature.
Geometry tetrahedron(bool attributes) {
    at::Tensor points =
        at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f}).view({4, 3});
    at::Tensor faces = at::tensor({0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}, at::kLong).view({4, 3});
    PointCloud cloud{points, at::Tensor(), at::Tensor()};
    if (attributes) {
        cloud.normals = points - 0.25f;
        cloud.colors =
            at::tensor({255, 0, 0, 0, 255, 0, 0, 0, 255, 9, 9, 9}, at::kByte).view({4, 3});
    }
    return {cloud, faces};
}

void write_clouds(const fs::path& dir, const std::string& extension) {
    fs::create_directories(dir);
    const Geometry mesh = tetrahedron(false);
    const Geometry rich = tetrahedron(true);
    const PointCloud random{uniform_random_points(12, 1)};
    for (bool binary : {true, false}) {
        const std::string kind = binary ? "binary" : "ascii";
        WriteOptions options{extension, binary};
        write_point_cloud((dir / ("cloud-" + kind + "." + extension)).string(), random, options);
        write_point_cloud((dir / ("attributes-" + kind + "." + extension)).string(), rich.cloud,
                          options);
        if (extension == "ply" || extension == "off" || extension == "obj")
            write_geometry((dir / ("mesh-" + kind + "." + extension)).string(), mesh, options);
    }
}

void write_ply_extras(const fs::path& dir) {
    // Faces before vertices (allowed by the format), a big-endian file, a skipped element with
    // a list, and a byte order mark.
    std::string faces_first =
        "ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list uchar int "
        "vertex_indices\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
        "z\nend_header\n";
    faces_first += '\3';
    for (int32_t i : {0, 1, 2}) put(faces_first, i);
    for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put(faces_first, v);
    write_bytes(dir / "faces-first.ply", faces_first);

    std::string big =
        "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\n"
        "property double y\nproperty double z\nproperty uchar red\nproperty uchar "
        "green\nproperty uchar blue\nend_header\n";
    for (int row = 0; row < 2; ++row) {
        for (double v : {1.0 * row, 2.0, 3.0}) {
            char bytes[8];
            std::memcpy(bytes, &v, 8);
            for (int i = 7; i >= 0; --i) big += bytes[i];
        }
        big += "\x10\x20\x30";
    }
    write_bytes(dir / "big-endian.ply", big);

    write_bytes(dir / "extra-elements.ply",
                "ply\nformat ascii 1.0\ncomment made by fuzz_make_seeds\nelement vertex 2\n"
                "property float x\nproperty float y\nproperty float z\nproperty float "
                "confidence\nelement edge 1\nproperty list uchar int vertex_pair\nend_header\n"
                "0 0 0 1\n1 1 1 0.5\n2 0 1\n");
    write_bytes(dir / "bom.ply",
                "\xEF\xBB\xBFply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty "
                "float y\nproperty float z\nend_header\n0.45 1 2\n");
}

void write_pcd_extras(const fs::path& dir) {
    write_bytes(dir / "counts.pcd",
                "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z histogram\nSIZE 4 4 4 4\nTYPE F F F F\n"
                "COUNT 1 1 1 3\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA "
                "ascii\n0 0 0 1 2 3\n1 1 1 4 5 6\n");
    std::string binary =
        "VERSION 0.7\nFIELDS intensity x y z\nSIZE 2 8 8 8\nTYPE U F F F\nCOUNT 1 1 1 1\n"
        "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
    for (int row = 0; row < 2; ++row) {
        put<uint16_t>(binary, 7);
        for (double v : {0.5, 1.0 * row, -2.0}) put(binary, v);
    }
    write_bytes(dir / "doubles.pcd", binary);
}

void write_xyz_extras(const fs::path& dir) {
    write_bytes(dir / "count-header.xyz", "3\n0 0 0\n1 0 0\n0 1 0\n");
    write_bytes(dir / "normals.txt", "0,0,0,0,0,1\n1,0,0,0,0,1\n");
    write_bytes(dir / "crlf.pts", "0 0 0\r\n1 2 3\r\n");
}

void write_stl(const fs::path& dir) {
    fs::create_directories(dir);
    write_bytes(dir / "ascii.stl",
                "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 "
                "0\nendloop\nendfacet\nendsolid t\n");
    std::string binary(80, ' ');
    put<uint32_t>(binary, 2);
    for (int facet = 0; facet < 2; ++facet) {
        for (float v : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 1.f * facet})
            put(binary, v);
        put<uint16_t>(binary, 0);
    }
    write_bytes(dir / "binary.stl", binary);
}

// A LAS 1.2 file of point data format `format` with two points (scale 0.01, offset 1).
std::string las_file(uint8_t format, uint16_t record_length) {
    std::string header = "LASF";
    header.append(20, '\0');               // source id, global encoding, GUID
    header += '\1';                        // version major
    header += '\2';                        // version minor
    header.append(64, '\0');               // system identifier, generating software
    put<uint16_t>(header, 1);              // day
    put<uint16_t>(header, 2026);           // year
    put<uint16_t>(header, 227);            // header size
    put<uint32_t>(header, 227);            // offset to point data
    put<uint32_t>(header, 0);              // variable length records
    header += static_cast<char>(format);   // point data format
    put<uint16_t>(header, record_length);  // point record length
    put<uint32_t>(header, 2);              // point count
    for (int i = 0; i < 5; ++i) put<uint32_t>(header, i == 0 ? 2 : 0);  // by return
    for (double v : {0.01, 0.01, 0.01, 1.0, 1.0, 1.0}) put(header, v);  // scale, offset
    for (double v : {3.0, 1.0, 3.0, 1.0, 3.0, 1.0}) put(header, v);     // max/min x, y, z
    for (int point = 0; point < 2; ++point) {
        std::string record;
        for (int32_t v : {100 * point, 200, -50}) put(record, v);
        record.resize(record_length, '\0');
        header += record;
    }
    return header;
}

void write_las(const fs::path& dir) {
    fs::create_directories(dir);
    write_bytes(dir / "format0.las", las_file(0, 20));
    write_bytes(dir / "format3.las", las_file(3, 34));
}

void write_checkpoints(const fs::path& dir) {
    fs::create_directories(dir);
    save_checkpoint((dir / "pugcn.pt").string(), *make_backbone({{"backbone", "pugcn"},
                                                                 {"ratio", 4},
                                                                 {"channels", 2},
                                                                 {"blocks", 1},
                                                                 {"k", 2},
                                                                 {"upsample_channels", 2},
                                                                 {"reconstruction_channels", 2},
                                                                 {"patch_size", 8},
                                                                 {"seed", 1}}));
    save_checkpoint((dir / "dispu.pt").string(), *make_backbone({{"backbone", "dispu"},
                                                                 {"ratio", 4},
                                                                 {"k", 2},
                                                                 {"growth", 2},
                                                                 {"blocks", 1},
                                                                 {"expand_channels", 2},
                                                                 {"feature_channels", 2},
                                                                 {"regressor_channels", 2},
                                                                 {"regressor_bottleneck", 2},
                                                                 {"refiner_channels", 2},
                                                                 {"refiner_out_channels", 2},
                                                                 {"attention_channels", 2},
                                                                 {"patch_size", 8},
                                                                 {"seed", 1}}));
    save_checkpoint((dir / "pudense.pt").string(),
                    *make_backbone({{"backbone", "pudense"},
                                    {"ratio", 4},
                                    {"channels", {4, 4, 4, 4, 4}},
                                    {"resolution", 4},
                                    {"patch_size", 8},
                                    {"seed", 1}}),
                    {{"step", 1}});
}

}  // namespace

// A torch.save archive of a state dict as PyTorch writes it: one float tensor and one
// transposed view of the same storage at an offset, an int64 scalar, and the _metadata BUILD.
void write_torch_archive(const fs::path& dir) {
    fs::create_directories(dir);
    auto text = [](std::string& out, const std::string& value) {
        out += 'X';
        put<uint32_t>(out, static_cast<uint32_t>(value.size()));
        out += value;
    };
    // Built from a literal with its length: it holds NUL bytes.
    static constexpr char kHead[] =
        "\x80\x02"
        "ccollections\nOrderedDict\nq\x00)Rq\x01(";
    std::string pickle(kHead, sizeof(kHead) - 1);
    struct Entry {
        const char *name, *key, *type;
        int numel, offset, rows, cols, row_stride, col_stride;
    };
    for (const Entry& e : {Entry{"conv.weight", "0", "FloatStorage", 6, 0, 2, 3, 3, 1},
                           Entry{"conv.view", "0", "FloatStorage", 6, 1, 2, 2, 1, 3},
                           Entry{"bn.num_batches_tracked", "1", "LongStorage", 1, 0, 0, 0, 0, 0}}) {
        text(pickle, e.name);
        pickle += "ctorch._utils\n_rebuild_tensor_v2\n((";
        text(pickle, "storage");
        pickle += std::string("ctorch\n") + e.type + "\n";
        text(pickle, e.key);
        text(pickle, "cuda:0");
        pickle += 'K';
        pickle += static_cast<char>(e.numel);
        pickle += "tQK";
        pickle += static_cast<char>(e.offset);
        if (e.rows == 0) {
            pickle += "))";
        } else {
            for (const auto [first, second] :
                 {std::pair{e.rows, e.cols}, std::pair{e.row_stride, e.col_stride}}) {
                pickle += 'K';
                pickle += static_cast<char>(first);
                pickle += 'K';
                pickle += static_cast<char>(second);
                pickle += '\x86';  // TUPLE2
            }
        }
        pickle +=
            "\x89"
            "ccollections\nOrderedDict\n)RtR";
    }
    pickle += "u}b.";
    std::string floats, longs;
    for (float v : {1.f, -2.f, 0.5f, 4.f, 8.f, -0.25f}) put(floats, v);
    put<int64_t>(longs, 7);
    std::string out;
    caffe2::serialize::PyTorchStreamWriter writer([&](const void* data, size_t size) {
        out.append(static_cast<const char*>(data), size);
        return size;
    });
    writer.writeRecord("data.pkl", pickle.data(), pickle.size());
    writer.writeRecord("data/0", floats.data(), floats.size());
    writer.writeRecord("data/1", longs.data(), longs.size());
    writer.writeEndOfFile();
    write_bytes(dir / "state-dict.pth", out);
}

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: fuzz_make_seeds OUT_DIR\n");
        return 2;
    }
    const fs::path out = argv[1];
    for (const char* extension : {"ply", "xyz", "off", "obj", "pcd"})
        write_clouds(out / (std::string("read_") + extension), extension);
    write_ply_extras(out / "read_ply");
    write_pcd_extras(out / "read_pcd");
    write_xyz_extras(out / "read_xyz");
    write_stl(out / "read_stl");
    write_las(out / "read_las");
    write_checkpoints(out / "load_checkpoint");
    write_torch_archive(out / "read_torch_archive");
    return 0;
}
