#include "support/hdf5_files.h"

#include <ATen/ATen.h>
#include <hdf5.h>

#include <stdexcept>

namespace pumeta::test {

namespace {

void check(herr_t status, const char* what) {
    if (status < 0) throw std::runtime_error(std::string("HDF5 test writer: ") + what);
}

hid_t checked(hid_t id, const char* what) {
    check(id < 0 ? -1 : 0, what);
    return id;
}

hid_t memory_type(at::ScalarType type) {
    switch (type) {
        case at::kFloat:
            return H5T_NATIVE_FLOAT;
        case at::kDouble:
            return H5T_NATIVE_DOUBLE;
        case at::kInt:
            return H5T_NATIVE_INT;
        default:
            throw std::runtime_error("HDF5 test writer: float32, float64 or int32 only");
    }
}

void write_dataset(hid_t file, hid_t create_groups, const Hdf5Dataset& d) {
    std::vector<hsize_t> dims;
    if (d.values.defined())
        for (int64_t size : d.values.sizes()) dims.push_back(static_cast<hsize_t>(size));
    else
        for (int64_t size : d.declared) dims.push_back(static_cast<hsize_t>(size));
    hid_t space = checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                          "H5Screate_simple");
    hid_t create = checked(H5Pcreate(H5P_DATASET_CREATE), "H5Pcreate");
    if (!d.values.defined()) {
        std::vector<hsize_t> chunk(dims.size(), 1);
        check(H5Pset_chunk(create, static_cast<int>(chunk.size()), chunk.data()), "H5Pset_chunk");
    }
    hid_t type = d.values.defined() ? memory_type(d.values.scalar_type()) : H5T_NATIVE_FLOAT;
    hid_t dataset =
        checked(H5Dcreate2(file, d.name.c_str(), type, space, create_groups, create, H5P_DEFAULT),
                "H5Dcreate2");
    if (d.values.defined()) {
        at::Tensor values = d.values.contiguous();
        check(H5Dwrite(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data_ptr()),
              "H5Dwrite");
    }
    H5Dclose(dataset);
    H5Pclose(create);
    H5Sclose(space);
}

}  // namespace

void write_hdf5(const std::string& path, const std::vector<Hdf5Dataset>& datasets) {
    hid_t file =
        checked(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), "H5Fcreate");
    hid_t create_groups = checked(H5Pcreate(H5P_LINK_CREATE), "H5Pcreate");
    check(H5Pset_create_intermediate_group(create_groups, 1), "H5Pset_create_intermediate_group");
    for (const Hdf5Dataset& d : datasets) write_dataset(file, create_groups, d);
    H5Pclose(create_groups);
    check(H5Fclose(file), "H5Fclose");
}

}  // namespace pumeta::test
