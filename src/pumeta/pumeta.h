// pumeta's public interface: the one header a program linking the library needs
// (find_package(pumeta CONFIG) gives the target pumeta::pumeta; README.md, "Using pumeta from
// C++"). A thin layer over the headers that do the work, which are installed too:
//   loading a model           inference/model_file.h  (serve(), models_dir())
//   upsampling a cloud        inference/upsample.h    (upsample_cloud(), UpsampleOptions)
//   reading and writing files geometry/io.h           (read_point_cloud(), write_point_cloud())
//   metrics                   metrics/metrics.h       (evaluate(), MetricReport)
//
// Points are float32 tensors of shape [N,3] on the CPU, or Points (one std::array per point).
// Every failure throws InputError (core/error.h) for bad input — a missing or malformed file, a
// wrong shape, non-finite coordinates, a ratio the model cannot serve — with a one-line message
// naming the file or argument and what is wrong, or InternalError for a failure of pumeta itself.
//
// Threads: upsample() does not modify its Model, but it sets LibTorch's process-wide thread
// count while the network runs (core/threads.h), so run one upsample() at a time per process.
// Logging goes through spdlog's default logger (warnings, e.g. a diverging adaptation); set its
// level or sink to silence or redirect it.
#pragma once

#include <ATen/core/Tensor.h>

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/metrics/metrics.h"

namespace pumeta {

struct ServedModel;

/// A cloud as plain values: one {x, y, z} per point.
using Points = std::vector<std::array<float, 3>>;

/// The largest output ratio accepted (the command line's --ratio bound).
inline constexpr int64_t kMaxUpsampleRatio = 256;

/// A trained model loaded for upsampling, and the output ratio it serves.
class Model {
  public:
    /// Loads the checkpoint `path` (a .pt file written by `pumeta train` or `meta-train`); an
    /// empty path loads the shipped default model for `ratio` (models/defaults.json, found in
    /// models_dir(): $PUMETA_MODELS, else the models installed with the library, else the
    /// source tree's models/). `ratio` (0..kMaxUpsampleRatio, 0 = the model's own) is the
    /// output ratio to serve: a model whose weights serve any ratio (PU-Dense) is rebuilt for
    /// it; any other model must have a ratio that `ratio` is a power of (16 with a 4× model:
    /// applied twice). InputError when the file is missing or not a model, or the ratio cannot
    /// be served.
    explicit Model(const std::string& path = "", int64_t ratio = 0);
    ~Model();
    Model(Model&&) noexcept;
    Model& operator=(Model&&) noexcept;

    /// The file loaded.
    const std::string& path() const { return path_; }
    /// The output ratio upsample() gives by default.
    int64_t ratio() const;
    /// The backbone's registered name ("pugcn", "dispu", "pudense", ...).
    std::string backbone() const;
    /// Meta-trained: upsample() adapts to each input first (its stored steps and step sizes)
    /// unless UpsampleSettings::tta_steps says otherwise.
    bool meta_trained() const;
    /// The model as the rest of the library takes it (inference/model_file.h).
    const ServedModel& served() const { return *served_; }

  private:
    std::string path_;
    std::unique_ptr<ServedModel> served_;
};

/// The settings of one upsample() call; each unset one keeps the model's default, as the
/// command line (`pumeta upsample`) does.
struct UpsampleSettings {
    /// Output ratio: 0 = Model::ratio(); otherwise a power of the model's ratio.
    int64_t ratio = 0;
    /// Test-time adaptation steps before predicting (paper Algorithm 2), 0..100000; unset: the
    /// model's (a meta-trained model's N, else 0).
    std::optional<int64_t> tta_steps;
    /// Inner step size (> 0) for every adapting tensor; unset: the model's (a meta-trained
    /// model's learned step sizes).
    std::optional<double> tta_lr;
    /// Seed of the adaptation's downsampler, the only randomness: same seed, same points.
    uint64_t seed = 0;
};

/// Upsamples `points` (float32 [N,3], finite; N >= 1, and a backbone may need a few points per
/// patch: PU-GCN 2) to exactly ratio·N points in the same frame, float32 [ratio·N,3]. Same
/// model, points and settings give the same output.
at::Tensor upsample(const Model& model, const at::Tensor& points,
                    const UpsampleSettings& settings = {});

/// upsample() on plain values.
Points upsample(const Model& model, const Points& points, const UpsampleSettings& settings = {});

/// The points of any readable file (geometry/io.h lists the formats; a mesh's vertices count as
/// points): float32 [N,3].
at::Tensor read_points(const std::string& path);

/// Writes `points` (float32 [N,3], finite) in the format of the file's extension (.ply, .xyz,
/// .pcd).
void write_points(const std::string& path, const at::Tensor& points);

/// CD, HD, PSNR (pc_error D1) and, with a mesh file, P2F of `pred` against `gt` (both float32
/// [N,3], N >= 1, finite), all in the GT frame as `pumeta metrics` computes them (evaluate() in
/// metrics/metrics.h). `mesh_path`: the ground-truth surface in gt's coordinates, or empty.
MetricReport metrics(const at::Tensor& pred, const at::Tensor& gt,
                     const std::string& mesh_path = "");

/// float32 [N,3] from plain values, and back (any [N,3] floating-point tensor).
at::Tensor to_tensor(const Points& points);
Points to_points(const at::Tensor& points);

}  // namespace pumeta
