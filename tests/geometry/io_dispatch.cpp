// What io.h does for every format: dispatch by extension, file errors, non-finite
// coordinates, writer checks and atomic writes.
#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <random>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;
using test::float_rows;
using test::index_rows;
using test::throws_input_error;

TEST(IoDispatch, FormatComesFromTheExtensionCaseInsensitively) {
    EXPECT_EQ(format_from_path("a/b/cloud.ply"), "ply");
    EXPECT_EQ(format_from_path("SCAN.PLY"), "ply");
    EXPECT_EQ(format_from_path("x.xyz"), "xyz");
    EXPECT_EQ(format_from_path("x.txt"), "xyz");
    EXPECT_EQ(format_from_path("x.pts"), "xyz");
    EXPECT_EQ(format_from_path("x.off"), "off");
    EXPECT_EQ(format_from_path("x.obj"), "obj");
    EXPECT_EQ(format_from_path("x.Stl"), "stl");
    EXPECT_EQ(format_from_path("x.pcd"), "pcd");
    EXPECT_EQ(format_from_path("dir.v2/x.las"), "las");
    EXPECT_EQ(readable_formats(),
              (std::vector<std::string>{"ply", "xyz", "off", "obj", "stl", "pcd", "las"}));
    EXPECT_EQ(writable_formats(), (std::vector<std::string>{"ply", "xyz", "off", "obj", "pcd"}));
}

TEST(IoDispatch, UnknownExtensionsListTheSupportedOnes) {
    EXPECT_TRUE(throws_input_error([] { format_from_path("model.3ds"); },
                                   {"model.3ds", "unknown file extension '.3ds'", ".ply", ".xyz",
                                    ".txt", ".pts", ".off", ".obj", ".stl", ".pcd", ".las"}));
    EXPECT_TRUE(throws_input_error([] { format_from_path("dir.d/README"); },
                                   {"dir.d/README", "no file extension", ".ply"}));
    EXPECT_TRUE(throws_input_error([] { read_point_cloud("missing.vtk"); },
                                   {"missing.vtk", "'.vtk'", ".las"}));
}

TEST(IoDispatch, LazIsRejectedWithAPointerToLaszip) {
    for (const std::string path : {"scan.laz", "SCAN.LAZ"})
        EXPECT_TRUE(throws_input_error([&] { format_from_path(path); },
                                       {path, "LAZ (compressed LAS) is not supported", "laszip"}));
    ReadOptions options;
    options.format = "laz";
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud("scan.bin", options); },
                                   {"scan.bin", "LAZ (compressed LAS) is not supported"}));
}

TEST(IoDispatch, FormatOptionOverridesTheExtension) {
    test::TempDir dir;
    const std::string path = dir.file("cloud.dat");
    test::write_file(path, "1 2 3\n4 5 6\n");
    ReadOptions read;
    read.format = "XYZ";
    EXPECT_TRUE(at::equal(read_point_cloud(path, read).points, float_rows({1, 2, 3, 4, 5, 6})));
    read.format = "vrml";
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path, read); },
                                   {path, "unknown format 'vrml'", "ply, xyz, off, obj, stl"}));

    const std::string written = dir.file("points.bin");
    WriteOptions write;
    write.format = "ply";
    write_point_cloud(written, PointCloud{float_rows({7, 8, 9}), {}, {}}, write);
    EXPECT_EQ(test::read_file(written).substr(0, 4), "ply\n");
    read.format = "ply";
    EXPECT_TRUE(at::equal(read_point_cloud(written, read).points, float_rows({7, 8, 9})));
}

TEST(IoDispatch, MissingEmptyAndDirectoryInputsAreReported) {
    test::TempDir dir;
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(dir.file("nope.ply")); },
                                   {dir.file("nope.ply"), "file not found"}));
    const std::string folder = dir.file("folder.ply");
    fs::create_directory(folder);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(folder); }, {folder, "is a directory"}));
    for (const char* extension : {"ply", "xyz", "off", "obj", "stl", "pcd", "las"}) {
        const std::string path = dir.file(std::string("empty.") + extension);
        test::write_file(path, "");
        EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "file is empty"}));
    }
    // Files that parse but hold nothing.
    const std::string blank = dir.file("blank.xyz");
    test::write_file(blank, "\n# only a comment\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(blank); }, {blank, "no points"}));
}

TEST(IoDispatch, OnlyRegularFilesAreRead) {
    test::TempDir dir;
    // A FIFO with no writer used to block the read forever.
    const std::string fifo = dir.file("pipe.xyz");
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(fifo); },
                                   {fifo, "is a FIFO", "only regular files are read"}));
    // A device without end used to grow until memory ran out.
    EXPECT_TRUE(throws_input_error([] { read_point_cloud("/dev/zero", {"xyz"}); },
                                   {"/dev/zero", "is a character device"}));
}

TEST(IoDispatch, Utf8ByteOrderMarkIsSkippedInTextFormats) {
    test::TempDir dir;
    const std::string bom = "\xEF\xBB\xBF";
    const std::vector<std::pair<std::string, std::string>> files = {
        {"a.xyz", "0.45 1 2\n3 4 5\n"},
        {"a.obj", "v 0.45 1 2\nv 3 4 5\n"},
        {"a.off", "OFF\n2 0 0\n0.45 1 2\n3 4 5\n"},
        {"a.ply",
         "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float "
         "y\nproperty float z\nend_header\n0.45 1 2\n3 4 5\n"},
        {"a.pcd",
         "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
         "HEIGHT 1\nPOINTS 2\nDATA ascii\n0.45 1 2\n3 4 5\n"}};
    for (const auto& [name, text] : files) {
        const std::string path = dir.file(name);
        test::write_file(path, bom + text);
        const PointCloud cloud = read_point_cloud(path);
        EXPECT_TRUE(at::equal(cloud.points, float_rows({0.45f, 1, 2, 3, 4, 5}))) << name;
    }
    const std::string only = dir.file("only.xyz");
    test::write_file(only, bom);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(only); }, {only, "byte order mark"}));
}

TEST(IoDispatch, Utf16TextIsRejectedClearly) {
    test::TempDir dir;
    const std::string path = dir.file("utf16.obj");
    std::string text = "\xFF\xFE";
    for (char c : std::string("v 0 0 0\n")) text += std::string{c, '\0'};
    test::write_file(path, text);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "UTF-16"}));
}

TEST(IoDispatch, NonFiniteCoordinatesAreRejectedOrDropped) {
    test::TempDir dir;
    const std::string path = dir.file("holes.xyz");
    test::write_file(path, "0 0 0\nnan 1 1\n2 2 2\n3 inf 3\n4 4 -inf\n5 5 5\n");
    EXPECT_TRUE(throws_input_error(
        [&] { read_point_cloud(path); },
        {path, "3 of 6 points", "NaN or infinite", "first is point 1", "drop_invalid"}));
    ReadOptions drop;
    drop.drop_invalid = true;
    EXPECT_TRUE(
        at::equal(read_point_cloud(path, drop).points, float_rows({0, 0, 0, 2, 2, 2, 5, 5, 5})));

    // Normals follow their points when rows are dropped.
    const std::string with_normals = dir.file("normals.xyz");
    test::write_file(with_normals, "0 0 0 1 0 0\nnan 0 0 0 1 0\n1 1 1 0 0 1\n");
    const PointCloud kept = read_point_cloud(with_normals, drop);
    EXPECT_TRUE(at::equal(kept.normals, float_rows({1, 0, 0, 0, 0, 1})));

    test::write_file(path, "nan 0 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path, drop); },
                                   {path, "no point has finite coordinates"}));
}

TEST(IoDispatch, MeshesRefuseToDropVerticesButTheirPointCloudsMay) {
    test::TempDir dir;
    const std::string path = dir.file("mesh.off");
    test::write_file(path, "OFF\n4 1 0\n0 0 0\n1 0 0\nnan 1 0\n0 1 0\n3 0 1 3\n");
    ReadOptions drop;
    drop.drop_invalid = true;
    EXPECT_TRUE(
        throws_input_error([&] { read_mesh(path); }, {path, "1 of 4 points", "first is point 2"}));
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path, drop); },
                                   {path, "cannot be dropped from a mesh", "vertex 2"}));
    EXPECT_TRUE(throws_input_error([&] { read_geometry(path, drop); },
                                   {path, "cannot be dropped from a mesh"}));
    EXPECT_TRUE(
        at::equal(read_point_cloud(path, drop).points, float_rows({0, 0, 0, 1, 0, 0, 0, 1, 0})));
}

TEST(IoDispatch, ReadMeshNeedsFacesAndPointCloudsDropThem) {
    test::TempDir dir;
    const std::string cloud = dir.file("cloud.xyz");
    test::write_file(cloud, "0 0 0\n1 0 0\n0 1 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(cloud); }, {cloud, "has no faces"}));
    EXPECT_FALSE(read_geometry(cloud).is_mesh());

    const std::string mesh = dir.file("mesh.obj");
    test::write_file(mesh, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    EXPECT_TRUE(read_geometry(mesh).is_mesh());
    EXPECT_EQ(read_point_cloud(mesh).size(), 3);
    EXPECT_TRUE(at::equal(read_mesh(mesh).faces, index_rows({0, 1, 2})));
}

TEST(IoDispatch, WritersCheckTheirInput) {
    test::TempDir dir;
    const TriangleMesh mesh{float_rows({0, 0, 0, 1, 0, 0, 0, 1, 0}), index_rows({0, 1, 2})};
    EXPECT_TRUE(throws_input_error([&] { write_mesh(dir.file("m.xyz"), mesh); },
                                   {"m.xyz", "cannot hold faces", ".ply, .off or .obj"}));
    EXPECT_TRUE(throws_input_error([&] { write_mesh(dir.file("m.pcd"), mesh); },
                                   {"m.pcd", "cannot hold faces"}));
    EXPECT_TRUE(throws_input_error([&] { write_mesh(dir.file("m.stl"), mesh); },
                                   {"m.stl", "cannot write stl", "ply, xyz, off, obj, pcd"}));
    EXPECT_TRUE(throws_input_error(
        [&] {
            write_mesh(dir.file("bad.ply"), {mesh.vertices, index_rows({0, 1, 3})});
        },
        {"bad.ply", "out of range"}));
    EXPECT_TRUE(throws_input_error(
        [&] {
            write_point_cloud(dir.file("bad.ply"), {at::zeros({4, 2}), {}, {}});
        },
        {"bad.ply", "[N,3]"}));
    EXPECT_TRUE(throws_input_error(
        [&] {
            write_point_cloud(dir.file("bad.ply"),
                              {at::zeros({4, 3}), {}, at::zeros({4, 3}, at::kFloat)});
        },
        {"bad.ply", "colors", "Byte"}));
    EXPECT_TRUE(throws_input_error(
        [&] {
            write_point_cloud(dir.file("bad.ply"), {at::zeros({4, 3}), at::zeros({3, 3}), {}});
        },
        {"bad.ply", "normals", "[4, 3]"}));
    EXPECT_TRUE(fs::is_empty(dir.path()));
}

TEST(IoDispatch, WritesAreAtomicAndLeaveNoTemporaryFiles) {
    test::TempDir dir;
    const std::string path = dir.file("cloud.ply");
    test::write_file(path, "old content");
    const at::Tensor points = uniform_random_points(100, 3);
    write_point_cloud(path, {points, {}, {}});
    EXPECT_TRUE(at::equal(read_point_cloud(path).points, points));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);

    // A target that cannot be replaced: the temporary file is removed again.
    const std::string blocked = dir.file("blocked.ply");
    fs::create_directory(blocked);
    test::write_file(blocked + "/keep", "x");
    EXPECT_TRUE(throws_input_error(
        [&] {
            write_point_cloud(blocked, {points, {}, {}});
        },
        {blocked, "cannot rename"}));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 2);

    EXPECT_TRUE(throws_input_error(
        [&] {
            write_point_cloud(dir.file("no/such/dir/c.ply"), {points, {}, {}});
        },
        {"no/such/dir/c.ply", "cannot write"}));
}

TEST(IoDispatch, WriteGeometryPicksMeshOrCloudAndAcceptsNonContiguousTensors) {
    test::TempDir dir;
    const at::Tensor transposed = float_rows({0, 1, 2, 3, 4, 5, 6, 7, 8}).t();
    ASSERT_FALSE(transposed.is_contiguous());
    const Geometry mesh{{transposed, {}, {}}, index_rows({0, 1, 2})};
    write_geometry(dir.file("m.obj"), mesh);
    const Geometry back = read_geometry(dir.file("m.obj"));
    EXPECT_TRUE(at::equal(back.cloud.points, transposed.contiguous()));
    EXPECT_TRUE(at::equal(back.faces, mesh.faces));

    const Geometry cloud{{transposed, {}, {}}, at::Tensor()};
    write_geometry(dir.file("c.xyz"), cloud);
    EXPECT_FALSE(read_geometry(dir.file("c.xyz")).is_mesh());
}

// Damaged files (bytes overwritten, files cut short) either still load or throw InputError:
// never another exception, a crash or a hang.
TEST(IoDispatch, CorruptedFilesLoadOrThrowInputError) {
    test::TempDir dir;
    const PointCloud cloud{uniform_random_points(12, 31), uniform_random_points(12, 32),
                           (at::arange(36, at::kLong) * 7 % 256).to(at::kByte).view({12, 3})};
    const at::Tensor faces = (at::arange(30, at::kLong) * 5 % 12).view({10, 3});
    std::vector<std::string> originals;
    for (const char* name : {"m.ply", "a.ply", "m.off", "m.obj"}) {
        const std::string path = dir.file(name);
        write_geometry(path, {cloud, faces}, {"", name[0] == 'm'});
        originals.push_back(path);
    }
    for (const char* name : {"c.xyz", "b.pcd", "a.pcd"}) {
        const std::string path = dir.file(name);
        write_point_cloud(path, cloud, {"", name[0] == 'b'});
        originals.push_back(path);
    }
    originals.push_back(test::io_fixture("square.stl"));
    originals.push_back(test::io_fixture("mixed_polygons.ply"));

    std::mt19937_64 rng(2024);
    for (const std::string& original : originals) {
        const std::string bytes = test::read_file(original);
        const std::string damaged_path =
            dir.file("damaged" + fs::path(original).extension().string());
        for (int trial = 0; trial < 80; ++trial) {
            std::string damaged = bytes;
            if (trial % 3 == 0) {
                damaged.resize(rng() % bytes.size());
            } else {
                for (int k = 0; k < 1 + trial % 4; ++k)
                    damaged[rng() % damaged.size()] = static_cast<char>(rng());
            }
            test::write_file(damaged_path, damaged);
            try {
                read_geometry(damaged_path);
            } catch (const InputError&) {
            } catch (const std::exception& error) {
                ADD_FAILURE() << original << " trial " << trial << ": " << error.what();
            }
        }
    }
}

}  // namespace
}  // namespace pumeta
