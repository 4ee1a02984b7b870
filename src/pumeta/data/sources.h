// The real models pumeta trains and evaluates on (fetched by scripts/get-data.sh into
// data/raw/) and the deterministic assignment of each to a split (docs/data.md).
#pragma once

#include <string>
#include <vector>

namespace pumeta {

struct SourceModel {
    std::string id;        ///< unique and stable, e.g. "furniture/Scopia/bed1"
    std::string path;      ///< file path relative to the raw data directory
    std::string source;    ///< "furniture", "cgal-cad", "cgal-scan", "cgal-aerial"
    std::string category;  ///< catalogue category ("Kitchen", ...) or "cad"/"scan"/"aerial"
    std::string name;      ///< human-readable name from the catalogue
    bool human = false;    ///< a human figure: evaluation only, never trained or tuned on
};

/// Every furniture model of the Sweet Home 3D catalogues under raw_dir/furniture, parsed from
/// each catalogue's PluginFurnitureCatalog.properties (name, category, tags, model path).
/// Human figures: the Reallusion catalogue, tags "Human"/"People", or mannequins.
std::vector<SourceModel> list_furniture(const std::string& raw_dir);

/// CGAL CAD parts (training), scanned statues (test-scans) and aerial scans (test-aerial)
/// under raw_dir/cgal/data; only files that exist are listed.
std::vector<SourceModel> list_cgal(const std::string& raw_dir);

/// The split of a model: "train", "val", "test-indist", "test-scans", "test-aerial" or
/// "test-humans". Non-human furniture goes to test-indist when the first 8 bytes of
/// SHA-256(id) as a fraction of 2^64 fall below test_fraction, else to val below
/// test_fraction + val_fraction, else to train. Deterministic, independent of file order.
std::string assign_split(const SourceModel& model, double test_fraction, double val_fraction);

}  // namespace pumeta
