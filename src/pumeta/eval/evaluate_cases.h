// Scoring a method on every test case of a split (dataset layout: data/dataset.h):
// upsample each case's input, score it against its GT in the GT frame, write a per-case CSV
// and a summary JSON. Every number in docs/ comes from here (`pumeta eval`).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/inference/upsample.h"
#include "pumeta/inference/zero_shot.h"

namespace pumeta {

struct EvalOptions {
    /// "network" (the model), "midpoint" (non-learned baseline), "input" (the input itself,
    /// unchanged: the reference any method must beat), "floor" (a second independent GT sample:
    /// the sampling floor; cases with gt_alt only), "external" (another program, see
    /// external_command), "zero-shot" (a fresh model of the given model's architecture trained
    /// on each input alone, see zero_shot), "grid-floor" (the ground truth through the model's
    /// patch pipeline on its output grid: what a gridded backbone cannot beat, eval/grid_floor.h).
    std::string method = "network";
    /// Method "external": a shell command upsampling {input} (an XYZ file) into {output} (XYZ)
    /// by {ratio}; e.g. "build/pumeta-ear {input} {output} --ratio {ratio}".
    std::string external_command;
    /// Input variant: "" = clean, or a key of the case's noisy inputs ("rel1", "abs0.01").
    std::string noise;
    /// Evaluate only the first max_cases cases (0 = all).
    int64_t max_cases = 0;
    /// Write each prediction as <out_dir>/pred/<case>.ply.
    bool save_predictions = false;
    /// ... or only those of the first N cases (figures of `pumeta report`).
    int64_t save_first = 0;
    UpsampleOptions upsample;
    /// Adapt on each case's ground truth (eval/oracle.h): a diagnostic reference of what
    /// upsample.adaptation's steps could gain with a perfect training signal, never a result.
    bool oracle = false;
    /// Method "zero-shot": the test-time training budget (its seed is upsample.seed).
    ZeroShotOptions zero_shot;
    /// Recorded in the summary.
    std::string command_line;
    /// Continue an interrupted evaluation of the same cases with the same options (the caller
    /// vouches for that: `pumeta reproduce` compares the cell's identity): the complete rows
    /// of out_dir/cases.csv.tmp are kept and their cases skipped. Without it out_dir's rows
    /// are started afresh.
    bool resume = false;
};

/// The prediction of options.method (every method but "floor", which needs a case's second GT
/// sample) for one input at upsample.ratio: input float32 [N,3] -> result.points [~rN,3], with
/// its seconds (and for "network" and "zero-shot" the adaptation's or training's figures).
/// `gt` is read by the oracle and "grid-floor" only; `name` names the input in the work files
/// of "external" (under out_dir/external) and its messages. model may be null unless the
/// method is "network", "zero-shot" or "grid-floor".
UpsampleResult predict_with_method(const Backbone* model, const at::Tensor& input,
                                   const at::Tensor& gt, const EvalOptions& options,
                                   const UpsampleOptions& upsample, const std::string& out_dir,
                                   const std::string& name);

/// cases_dir: a cases/<set>/x<r> directory holding cases.json. model may be null unless the
/// method is "network" or "zero-shot"; it must serve the cases' ratio (options.upsample.ratio
/// is set to it). Returns the summary (also written to out_dir/summary.json;
/// per-case rows to out_dir/cases.csv, written row by row to out_dir/cases.csv.tmp until the
/// last case, so that an interrupted run can resume).
nlohmann::json evaluate_cases(const std::string& cases_dir, const Backbone* model,
                              const EvalOptions& options, const std::string& out_dir);

}  // namespace pumeta
