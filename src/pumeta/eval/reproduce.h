// `pumeta reproduce`: the paper's five tables on this repository's data. Every cell comes
// from one `evaluate_cases` run (the code of `pumeta eval`) whose per-case scores are kept in
// <out>/runs/...; a run whose spec (cases, method, model hash, options) is unchanged is reused,
// so an interrupted reproduction resumes where it stopped. Writes <out>/tables.md and
// <out>/tables.json.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/eval/reproduce_config.h"

namespace pumeta {

/// Runs (or reuses) every evaluation the tables need and writes them; returns tables.json.
/// With evaluate = false (`--tables-only`) it only reuses: a cell not evaluated yet shows as
/// missing ("—") and is listed under "Missing rows".
nlohmann::json reproduce(const ReproduceConfig& config, const std::string& out_dir,
                         const std::string& command_line, bool evaluate = true);

}  // namespace pumeta
