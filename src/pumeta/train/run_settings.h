// The settings every training run shares (TrainConfig and MetaTrainConfig derive from them):
// its data, directory, length, cadence, seed and processes.
#pragma once

#include <cstdint>
#include <string>

#include "pumeta/data/patch_set.h"
#include "pumeta/distributed/process_group.h"

namespace pumeta {

struct RunSettings {
    /// PatchSet files written by make-dataset (train-x<r>.tensors / val-x<r>.tensors), or
    /// HDF5 patch files (.h5, PU-GAN's and PU1K's; data/hdf5_patches.h); no validation without
    /// val_data.
    std::string train_data;
    std::string val_data;
    /// The datasets of an HDF5 patch file holding the input and the GT patches.
    std::string data_input_key = Hdf5PatchKeys().input;
    std::string data_gt_key = Hdf5PatchKeys().gt;
    std::string run_dir;
    int64_t steps = 0;
    /// How inputs are drawn from GT patches: fps, random or nonuniform.
    std::string sampler = "fps";
    bool augment = true;
    int64_t log_every = 20;
    int64_t val_every = 500;
    int64_t checkpoint_every = 500;
    uint64_t seed = 1;
    /// Processes and rendezvous; a batch must be a multiple of the world size.
    DistributedConfig distributed;
};

/// Visits RunSettings' fields by their JSON names (core/json_fields.h).
template <class Self, class Visit>
void visit_run_settings(Self& s, Visit&& visit) {
    visit("train_data", s.train_data);
    visit("val_data", s.val_data);
    visit("data_input_key", s.data_input_key);
    visit("data_gt_key", s.data_gt_key);
    visit("run_dir", s.run_dir);
    visit("steps", s.steps);
    visit("sampler", s.sampler);
    visit("augment", s.augment);
    visit("log_every", s.log_every);
    visit("val_every", s.val_every);
    visit("checkpoint_every", s.checkpoint_every);
    visit("seed", s.seed);
    visit("distributed", s.distributed);
}

/// The learning rate of a run's optimiser: max(floor, lr · rate^(step / steps)), an
/// exponential decay (PU-GCN's schedule; the paper's outer loop with floor 0).
struct LrSchedule {
    double lr = 1e-3;
    double rate = 1.0;
    int64_t steps = 1;
    double floor = 0;

    double at(int64_t step) const;
};

/// Visits a schedule's fields under a config's JSON names (`floor` null: not a config field).
template <class Schedule, class Visit>
void visit_schedule(Schedule& s, Visit&& visit, const char* lr, const char* rate, const char* steps,
                    const char* floor = nullptr) {
    visit(lr, s.lr);
    visit(rate, s.rate);
    visit(steps, s.steps);
    if (floor) visit(floor, s.floor);
}

/// InputError naming `context` and the field `lr` / `steps` unless lr > 0 and steps >= 1.
void check_schedule(const LrSchedule& s, const std::string& context, const char* lr,
                    const char* steps);

/// The HDF5 dataset keys of the settings.
Hdf5PatchKeys hdf5_patch_keys(const RunSettings& s);

/// InputError naming `context` unless train_data, run_dir and the HDF5 keys are given, steps and
/// the cadences are valid, the sampler is known, and `batch` (the field `batch_name`) is at least 1
/// and splits evenly over the processes.
void check_run_settings(const RunSettings& s, const std::string& context,
                        const std::string& batch_name, int64_t batch);

}  // namespace pumeta
