#include "pumeta/data/hdf5_patches.h"

#include <ATen/ATen.h>
#include <hdf5.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

/// An HDF5 identifier, closed on destruction by the function that matches its kind.
class Handle {
  public:
    Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
    ~Handle() {
        if (id_ >= 0) close_(id_);
    }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;

    hid_t get() const { return id_; }
    bool valid() const { return id_ >= 0; }

  private:
    hid_t id_;
    herr_t (*close_)(hid_t);
};

/// The names of the links in the file's root group, for the message about a missing key.
std::string root_names(hid_t file) {
    constexpr hsize_t kMaxListed = 20;
    H5G_info_t info;
    if (H5Gget_info(file, &info) < 0 || info.nlinks == 0) return "the file holds no datasets";
    std::string names;
    for (hsize_t i = 0; i < std::min(info.nlinks, kMaxListed); ++i) {
        ssize_t length =
            H5Lget_name_by_idx(file, ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
        if (length < 0) continue;
        std::string name(static_cast<size_t>(length) + 1, '\0');
        H5Lget_name_by_idx(file, ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(), name.size(),
                           H5P_DEFAULT);
        name.resize(static_cast<size_t>(length));
        names += (names.empty() ? "" : ", ") + name;
    }
    if (info.nlinks > kMaxListed) names += fmt::format(" and {} more", info.nlinks - kMaxListed);
    return "the file holds: " + names;
}

/// Whether `key` names a link in the file; every group on its path must exist first (HDF5
/// fails, rather than answering no, on a missing intermediate group).
bool link_exists(hid_t file, const std::string& key) {
    if (key.empty()) return false;
    for (size_t slash = key.find('/', 1); slash != std::string::npos;
         slash = key.find('/', slash + 1))
        if (H5Lexists(file, key.substr(0, slash).c_str(), H5P_DEFAULT) <= 0) return false;
    return H5Lexists(file, key.c_str(), H5P_DEFAULT) > 0;
}

/// That reading `dataset` (shape `dims`, numbers of `bytes` bytes) allocates no more than its
/// shape says: its data was written, uncompressed data fills exactly its shape, and chunks are
/// of a sane size.
void check_storage(const std::string& path, hid_t dataset, const std::string& key,
                   const std::array<hsize_t, 3>& dims, size_t bytes) {
    // Data never written reads as the fill value, however large the shape claims to be.
    const hsize_t stored = H5Dget_storage_size(dataset);
    if (stored == 0) throw_input_error(path, "'{}' holds no stored data", key);
    Handle create(H5Dget_create_plist(dataset), H5Pclose);
    if (!create.valid()) throw_input_error(path, "the layout of '{}' cannot be read", key);
    const H5D_layout_t layout = H5Pget_layout(create.get());
    const hsize_t needed = dims[0] * dims[1] * dims[2] * bytes;
    if (layout == H5D_CONTIGUOUS && stored != needed)
        throw_input_error(path, "'{}' stores {} bytes where its shape needs {}", key, stored,
                          needed);
    if (layout == H5D_CHUNKED) {
        // Each chunk is decompressed whole; writers use chunks of about a megabyte.
        constexpr hsize_t kMaxChunkBytes = hsize_t{1} << 28;
        std::array<hsize_t, 3> chunk{};
        const bool ranked = H5Pget_chunk(create.get(), 3, chunk.data()) == 3;
        hsize_t chunk_bytes = bytes;  // saturates just above the limit
        for (hsize_t size : chunk)
            chunk_bytes = size > kMaxChunkBytes ? kMaxChunkBytes + 1
                                                : std::min(chunk_bytes * size, kMaxChunkBytes + 1);
        if (!ranked || chunk_bytes > kMaxChunkBytes)
            throw_input_error(path, "'{}' has chunks of the wrong rank or over 256 MiB", key);
    }
}

/// The xyz columns of the patches in dataset `key`: float32 [P, n, 3], checked as
/// read_hdf5_patches describes.
at::Tensor read_patches(const std::string& path, hid_t file, const std::string& key) {
    if (!link_exists(file, key))
        throw_input_error(path, "no dataset '{}' ({})", key, root_names(file));
    Handle dataset(H5Dopen2(file, key.c_str(), H5P_DEFAULT), H5Dclose);
    if (!dataset.valid()) throw_input_error(path, "'{}' is not a dataset", key);
    Handle type(H5Dget_type(dataset.get()), H5Tclose);
    if (!type.valid() || H5Tget_class(type.get()) != H5T_FLOAT)
        throw_input_error(path, "'{}' does not hold floating-point numbers", key);
    // Half to quadruple precision; a damaged type can claim gigabytes per number, which the
    // read's conversion buffer would then allocate.
    const size_t bytes = H5Tget_size(type.get());
    if (bytes < 2 || bytes > 16)
        throw_input_error(path, "'{}' holds floating-point numbers of {} bytes", key, bytes);
    Handle space(H5Dget_space(dataset.get()), H5Sclose);
    const int rank = space.valid() ? H5Sget_simple_extent_ndims(space.get()) : -1;
    if (rank < 0) throw_input_error(path, "the shape of '{}' cannot be read", key);
    std::array<hsize_t, H5S_MAX_RANK> dims{};
    H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
    std::string shape;
    for (int d = 0; d < rank; ++d) shape += (d ? ", " : "") + std::to_string(dims[d]);
    if (rank != 3 || dims[0] == 0 || dims[1] == 0 || dims[2] < 3)
        throw_input_error(path, "'{}' has shape [{}], expected [patches, points, 3 or more]", key,
                          shape);
    const auto limit = static_cast<hsize_t>(kMaxHdf5PatchPoints);
    if (dims[0] > limit || dims[1] > limit || dims[0] * dims[1] > limit)
        throw_input_error(path, "'{}' has shape [{}]: more than {} points", key, shape, limit);
    if (dims[2] > 1024)
        throw_input_error(path, "'{}' has shape [{}]: more than 1024 columns", key, shape);
    check_storage(path, dataset.get(), key, {dims[0], dims[1], dims[2]}, bytes);

    const std::array<hsize_t, 3> start = {0, 0, 0}, count = {dims[0], dims[1], 3};
    if (H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                            nullptr) < 0)
        throw_input_error(path, "the xyz columns of '{}' cannot be selected", key);
    Handle memory(H5Screate_simple(3, count.data(), nullptr), H5Sclose);
    at::Tensor patches =
        at::empty({static_cast<int64_t>(dims[0]), static_cast<int64_t>(dims[1]), 3}, at::kFloat);
    if (!memory.valid() || H5Dread(dataset.get(), H5T_NATIVE_FLOAT, memory.get(), space.get(),
                                   H5P_DEFAULT, patches.data_ptr<float>()) < 0)
        throw_input_error(path,
                          "the data of '{}' cannot be read (a truncated or damaged file, or a "
                          "compression filter this HDF5 library lacks)",
                          key);
    at::Tensor bad = at::logical_not(at::isfinite(patches)).any(2).any(1);
    if (bad.any().item<bool>())
        throw_input_error(path, "'{}' patch {} has a non-finite coordinate", key,
                          bad.nonzero()[0][0].item<int64_t>());
    return patches;
}

/// Per patch, the index of its point nearest the patch centroid. patches: float32 [P, m, 3].
at::Tensor central_points(const at::Tensor& patches) {
    constexpr int64_t kChunk = 4096;  // bounds the temporary copy of the patches
    std::vector<at::Tensor> parts;
    for (int64_t begin = 0; begin < patches.size(0); begin += kChunk) {
        at::Tensor chunk = patches.slice(0, begin, std::min(begin + kChunk, patches.size(0)));
        at::Tensor offsets = chunk - chunk.mean(1, /*keepdim=*/true);
        parts.push_back(offsets.pow(2).sum(2).argmin(1));
    }
    return at::cat(parts);
}

}  // namespace

PatchSet read_hdf5_patches(const std::string& path, const Hdf5PatchKeys& keys, int64_t ratio) {
    namespace fs = std::filesystem;
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    std::error_code error;
    if (!fs::exists(path, error)) throw_input_error(path, "file not found");
    if (!fs::is_regular_file(path, error)) throw_input_error(path, "not a file");
    if (H5Fis_hdf5(path.c_str()) <= 0) throw_input_error(path, "not an HDF5 file");
    Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!file.valid())
        throw_input_error(path, "the HDF5 file cannot be opened (truncated or damaged)");

    at::Tensor input = read_patches(path, file.get(), keys.input);
    at::Tensor gt = read_patches(path, file.get(), keys.gt);
    const int64_t patches = gt.size(0), n = input.size(1), m = gt.size(1);
    if (input.size(0) != patches)
        throw_input_error(path, "'{}' has {} patches but '{}' has {}", keys.input, input.size(0),
                          keys.gt, patches);
    if (ratio > 0 && m != ratio * n)
        throw_input_error(path,
                          "'{}' has {} points per patch, not {} × the {} of '{}' (the model's "
                          "ratio {}; data_gt_key names another dataset)",
                          keys.gt, m, ratio, n, keys.input, ratio);
    if (m % n != 0 || m / n < 2)
        throw_input_error(path,
                          "'{}' has {} points per patch, not a whole multiple (2 or more) of the "
                          "{} of '{}'",
                          keys.gt, m, n, keys.input);

    PatchSet set;
    set.ratio = m / n;
    set.patch_points = n;
    set.points = gt.reshape({patches * m, 3});
    set.offsets = at::arange(patches + 1, at::kLong) * m;
    set.seeds = at::stack({at::arange(patches, at::kLong), central_points(gt)}, 1);
    set.ids.reserve(patches);
    for (int64_t p = 0; p < patches; ++p) set.ids.push_back(std::to_string(p));
    return set;
}

}  // namespace pumeta
