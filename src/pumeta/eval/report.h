// `pumeta report RESULTS -o REPORT`: a self-contained HTML page of a `pumeta reproduce` run
// (its tables, plus figures): for the first objects of each set of Table I, every method's
// output next to the input and the GT with per-point error colouring (the paper's Fig. 3/4),
// and plots of Table V (CD and time vs N) and Table II (CD vs noise). Everything lives in
// REPORT (index.html + figures/*.png) and opens from a file URL without network.
#pragma once

#include <string>

namespace pumeta {

struct ReportSummary {
    int object_figures = 0;
    int plots = 0;
};

/// InputError when results_dir holds no tables.json. The test cases (GT of the figures) are
/// read from the dataset directory recorded in tables.json.
ReportSummary write_report(const std::string& results_dir, const std::string& out_dir);

}  // namespace pumeta
