// The Python module `pumeta`: upsampling, point files and metrics on NumPy arrays, through the
// library's public interface (pumeta/pumeta.h). Points go in as any real [N,3] array (float64 is
// converted) and come out as float32 [N,3]. The library's errors become Python exceptions with
// the command line's one-line message: bad input is ValueError, or an OSError subclass when a
// file the call reads cannot be opened (or one it writes has no directory to go to); a failure
// of pumeta itself is RuntimeError. No C++ exception reaches the interpreter.
#include <ATen/ATen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "pumeta/inference/model_file.h"
#include "pumeta/pumeta.h"

namespace py = pybind11;
namespace fs = std::filesystem;

namespace {

/// The files one call reads and writes, to tell a file that cannot be opened (OSError) from
/// one whose content is wrong (ValueError).
struct Files {
    std::vector<std::string> reads;
    std::string write;
    /// The call loads the shipped default model: files under models_dir() are read too.
    bool default_model = false;

    static Files reading(const std::string& file) { return {{file}, "", false}; }
    static Files writing(const std::string& file) { return {{}, file, false}; }
};

/// Sets Python's error and unwinds to pybind11, which hands it to the interpreter.
[[noreturn]] void throw_python(PyObject* type, const std::string& message) {
    PyErr_SetString(type, message.c_str());
    throw py::error_already_set();
}

/// The OSError subclass for a file that cannot be read, or nullptr when it can be.
PyObject* read_failure(const std::string& file) {
    std::error_code error;
    const fs::file_status status = fs::status(file, error);
    if (!fs::exists(status)) return PyExc_FileNotFoundError;
    if (fs::is_directory(status)) return PyExc_IsADirectoryError;
    if (::access(file.c_str(), R_OK) != 0) return PyExc_PermissionError;
    if (!fs::is_regular_file(status)) return PyExc_OSError;
    return nullptr;
}

/// The OSError subclass for a file that cannot be written, or nullptr when it can be.
PyObject* write_failure(const std::string& file) {
    std::error_code error;
    if (fs::is_directory(file, error)) return PyExc_IsADirectoryError;
    fs::path directory = fs::path(file).parent_path();
    if (directory.empty()) directory = ".";
    const fs::file_status status = fs::status(directory, error);
    if (!fs::exists(status)) return PyExc_FileNotFoundError;
    if (!fs::is_directory(status)) return PyExc_NotADirectoryError;
    if (::access(directory.c_str(), W_OK) != 0) return PyExc_PermissionError;
    return nullptr;
}

/// Python's exception type for an InputError with `message` ("<file>: <what is wrong>").
PyObject* input_error_type(const std::string& message, const Files& files) {
    auto names = [&](const std::string& file) { return message.rfind(file + ": ", 0) == 0; };
    for (const std::string& file : files.reads)
        if (names(file))
            if (PyObject* type = read_failure(file)) return type;
    if (files.default_model) {
        const std::string file = message.substr(0, message.find(": "));
        if (file.rfind(pumeta::models_dir(), 0) == 0)
            if (PyObject* type = read_failure(file)) return type;
    }
    if (!files.write.empty() && names(files.write))
        if (PyObject* type = write_failure(files.write)) return type;
    return PyExc_ValueError;
}

/// Runs `work` (which releases the GIL around the library's work), turning every C++ exception
/// into a Python one.
template <typename Work>
auto guarded(const Files& files, Work&& work) -> decltype(work()) {
    try {
        return work();
    } catch (const py::error_already_set&) {
        throw;
    } catch (const pumeta::InputError& e) {
        throw_python(input_error_type(e.what(), files), e.what());
    } catch (const pumeta::InternalError& e) {
        throw_python(PyExc_RuntimeError, e.what());
    } catch (const std::bad_alloc&) {
        throw_python(PyExc_MemoryError, "pumeta: out of memory");
    } catch (const std::exception& e) {
        // The first line only: LibTorch's errors append a C++ backtrace (as the CLI's main()).
        const std::string message = e.what();
        throw_python(PyExc_RuntimeError, message.substr(0, message.find('\n')));
    }
}

/// `object` (anything numpy.asarray takes) as float32 [N,3]; ValueError naming `what` unless
/// it is an array of real numbers of shape [N,3].
at::Tensor points_from_python(const py::object& object, const std::string& what) {
    const py::array array = py::array::ensure(object);
    if (!array) throw_python(PyExc_ValueError, what + ": expected an array of shape [N,3]");
    const char kind = array.dtype().kind();
    if (kind != 'f' && kind != 'i' && kind != 'u')
        throw_python(PyExc_ValueError, what + ": expected real numbers, found dtype " +
                                           py::str(array.dtype()).cast<std::string>());
    if (array.ndim() != 2 || array.shape(1) != 3)
        throw_python(PyExc_ValueError, what + ": expected an array of shape [N,3], found shape " +
                                           py::str(array.attr("shape")).cast<std::string>());
    const auto floats =
        py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
    if (!floats) throw_python(PyExc_ValueError, what + ": cannot convert to float32");
    at::Tensor points = at::empty({floats.shape(0), 3}, at::kFloat);
    if (floats.size() > 0)
        std::memcpy(points.data_ptr<float>(), floats.data(), floats.size() * sizeof(float));
    return points;
}

py::array_t<float> points_to_python(const at::Tensor& points) {
    const at::Tensor values = points.to(at::kCPU, at::kFloat).contiguous();
    py::array_t<float> array({values.size(0), int64_t{3}});
    if (values.numel() > 0)
        std::memcpy(array.mutable_data(), values.data_ptr<float>(), values.numel() * sizeof(float));
    return array;
}

py::array_t<float> upsample_points(const py::object& points, const std::optional<fs::path>& model,
                                   std::optional<int64_t> ratio, std::optional<int64_t> tta_steps,
                                   std::optional<double> tta_lr, uint64_t seed) {
    const at::Tensor input = points_from_python(points, "points");
    Files files;
    if (model)
        files.reads = {model->string()};
    else
        files.default_model = true;
    const at::Tensor output = guarded(files, [&] {
        py::gil_scoped_release release;
        const pumeta::Model loaded(model ? model->string() : "", ratio.value_or(0));
        pumeta::UpsampleSettings settings;
        settings.tta_steps = tta_steps;
        settings.tta_lr = tta_lr;
        settings.seed = seed;
        return pumeta::upsample(loaded, input, settings);
    });
    return points_to_python(output);
}

py::array_t<float> read_cloud(const fs::path& path) {
    const std::string file = path.string();
    const at::Tensor points = guarded(Files::reading(file), [&] {
        py::gil_scoped_release release;
        return pumeta::read_points(file);
    });
    return points_to_python(points);
}

void write_cloud(const fs::path& path, const py::object& points) {
    const std::string file = path.string();
    const at::Tensor values = points_from_python(points, "points");
    guarded(Files::writing(file), [&] {
        py::gil_scoped_release release;
        pumeta::write_points(file, values);
    });
}

py::dict compute_metrics(const py::object& pred, const py::object& gt,
                         const std::optional<fs::path>& mesh) {
    const at::Tensor pred_points = points_from_python(pred, "pred");
    const at::Tensor gt_points = points_from_python(gt, "gt");
    const std::string mesh_file = mesh ? mesh->string() : "";
    const pumeta::MetricReport report = guarded(mesh ? Files::reading(mesh_file) : Files{}, [&] {
        py::gil_scoped_release release;
        return pumeta::metrics(pred_points, gt_points, mesh_file);
    });
    py::dict out;
    out["cd"] = report.cd;
    out["hd"] = report.hd;
    out["hd_legacy"] = report.hd_legacy;
    out["psnr"] = report.psnr;
    out["p2f"] = report.p2f ? py::cast(*report.p2f) : py::none();
    out["n_pred"] = report.n_pred;
    out["n_gt"] = report.n_gt;
    return out;
}

}  // namespace

PYBIND11_MODULE(pumeta, m) {
    m.doc() =
        "pumeta: point-cloud upsampling with test-time adaptation (the C++ library's "
        "pumeta/pumeta.h). Points are numpy arrays of shape [N,3].";
    // The library's warnings (e.g. a diverging adaptation) go to stderr, as the command line's.
    std::shared_ptr<spdlog::logger> logger = spdlog::get("pumeta");
    if (!logger) logger = spdlog::stderr_color_mt("pumeta");
    spdlog::set_default_logger(logger);
    spdlog::set_level(spdlog::level::warn);

    m.def("upsample", &upsample_points, py::arg("points"), py::arg("model") = py::none(),
          py::arg("ratio") = py::none(), py::arg("tta_steps") = py::none(),
          py::arg("tta_lr") = py::none(), py::arg("seed") = 0,
          R"(Upsample a cloud to exactly ratio * N points, float32 [ratio * N, 3].

points: array of shape [N,3], finite (float64 and integers are converted).
model: a checkpoint path; None: the shipped default model for the ratio (as `pumeta upsample`).
ratio: output ratio; None: the model's own (a power of it applies the model repeatedly).
tta_steps: test-time adaptation steps; None: the model's (a meta-trained model's, else 0).
tta_lr: inner step size; None: the model's.
seed: seed of the adaptation's downsampler (same seed, same points).
Raises ValueError for bad input (shape, NaN, a ratio the model cannot serve, a file that is not
a model) and OSError when the model file cannot be opened.)");
    m.def("read", &read_cloud, py::arg("path"),
          R"(The points of a cloud or mesh file (.ply .xyz .off .obj .stl .pcd .las) as float32
[N,3]. Raises OSError when it cannot be opened, ValueError when it is malformed.)");
    m.def("write", &write_cloud, py::arg("path"), py::arg("points"),
          R"(Write points [N,3] as .ply, .xyz or .pcd (by extension), atomically.)");
    m.def("metrics", &compute_metrics, py::arg("pred"), py::arg("gt"), py::arg("mesh") = py::none(),
          R"(CD, HD, PSNR (pc_error D1) and, with a mesh file in gt's coordinates, P2F of pred
against gt, in the GT frame as `pumeta metrics` computes them. Returns a dict with cd, hd,
hd_legacy, psnr, p2f (None without a mesh), n_pred and n_gt.)");
}
