#include "pumeta/data/sources.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>

#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
    return s;
}

bool contains(const std::string& text, const std::string& word) {
    return lower(text).find(lower(word)) != std::string::npos;
}

/// Java .properties files are ISO-8859-1: each byte is one code point.
std::string latin1_to_utf8(const std::string& text) {
    std::string out;
    out.reserve(text.size());
    for (unsigned char c : text) {
        if (c < 0x80) {
            out += static_cast<char>(c);
        } else {
            out += static_cast<char>(0xC0 | (c >> 6));
            out += static_cast<char>(0x80 | (c & 0x3F));
        }
    }
    return out;
}

/// Parses "key#N=value" lines of a catalogue into N -> {key -> value}.
std::map<int, std::map<std::string, std::string>> parse_catalogue(const fs::path& file) {
    std::ifstream in(file);
    if (!in) throw_input_error(file.string(), "cannot open furniture catalogue");
    std::map<int, std::map<std::string, std::string>> entries;
    std::string line;
    while (std::getline(in, line)) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        auto hash = line.find('#');
        auto eq = line.find('=');
        if (line.empty() || line[0] == '#' || hash == std::string::npos ||
            eq == std::string::npos || hash > eq)
            continue;
        std::string index = line.substr(hash + 1, eq - hash - 1);
        if (index.empty() || index.find_first_not_of("0123456789") != std::string::npos) continue;
        entries[std::stoi(index)][line.substr(0, hash)] = latin1_to_utf8(line.substr(eq + 1));
    }
    return entries;
}

}  // namespace

std::vector<SourceModel> list_furniture(const std::string& raw_dir) {
    fs::path root = fs::path(raw_dir) / "furniture";
    if (!fs::is_directory(root))
        throw_input_error(root.string(), "missing furniture data: run scripts/get-data.sh");
    std::vector<fs::path> catalogues;
    for (const auto& entry : fs::directory_iterator(root))
        if (entry.is_directory()) catalogues.push_back(entry.path());
    std::sort(catalogues.begin(), catalogues.end());

    std::vector<SourceModel> models;
    for (const fs::path& dir : catalogues) {
        std::string catalogue = dir.filename().string();
        for (const auto& [index, fields] :
             parse_catalogue(dir / "PluginFurnitureCatalog.properties")) {
            auto model_it = fields.find("model");
            if (model_it == fields.end()) continue;
            std::string model = model_it->second;
            if (!model.empty() && model[0] == '/') model.erase(0, 1);
            if (lower(fs::path(model).extension().string()) != ".obj") continue;
            if (!fs::exists(dir / model)) continue;
            // A named reference: C++17 lambdas cannot capture a structured binding (clang).
            const auto& properties = fields;
            auto get = [&](const char* key) {
                auto it = properties.find(key);
                return it == properties.end() ? std::string() : it->second;
            };
            SourceModel m;
            m.path = (fs::path("furniture") / catalogue / model).string();
            m.id = "furniture/" + catalogue + "/" + fs::path(model).stem().string();
            m.source = "furniture";
            m.category = get("category");
            m.name = get("name");
            std::string tags = get("tags");
            m.human = catalogue == "Reallusion" || contains(tags, "human") ||
                      contains(tags, "people") || contains(m.name, "mannequin") ||
                      (m.category == "Characters" &&
                       (contains(m.name, "male") || contains(m.name, "boy") ||
                        contains(m.name, "girl") || contains(m.name, "man")));
            models.push_back(std::move(m));
        }
    }
    // A model file referenced twice (same id) is kept once.
    std::sort(models.begin(), models.end(),
              [](const SourceModel& a, const SourceModel& b) { return a.id < b.id; });
    models.erase(
        std::unique(models.begin(), models.end(),
                    [](const SourceModel& a, const SourceModel& b) { return a.id == b.id; }),
        models.end());
    return models;
}

std::vector<SourceModel> list_cgal(const std::string& raw_dir) {
    struct Entry {
        const char* file;
        const char* source;
        const char* category;
    };
    // CAD parts train; scanned statues and aerial scans are out-of-distribution test sets.
    static const Entry kEntries[] = {
        {"meshes/anchor.off", "cgal-cad", "cad"},
        {"meshes/blade.off", "cgal-cad", "cad"},
        {"meshes/couplingdown.off", "cgal-cad", "cad"},
        {"meshes/dragknob.off", "cgal-cad", "cad"},
        {"meshes/fandisk.off", "cgal-cad", "cad"},
        {"meshes/handle.off", "cgal-cad", "cad"},
        {"meshes/joint.off", "cgal-cad", "cad"},
        {"meshes/mech-holes-shark.off", "cgal-cad", "cad"},
        {"meshes/part.off", "cgal-cad", "cad"},
        {"meshes/pinion.off", "cgal-cad", "cad"},
        {"meshes/rotor_small.off", "cgal-cad", "cad"},
        {"meshes/turbine.off", "cgal-cad", "cad"},
        {"meshes/spool.off", "cgal-cad", "cad"},
        {"meshes/tripod.off", "cgal-cad", "cad"},
        {"meshes/beam.off", "cgal-cad", "cad"},
        {"meshes/bunny00.off", "cgal-scan", "scan"},
        {"meshes/armadillo.off", "cgal-scan", "scan"},
        {"meshes/ChineseDragon-10kv.off", "cgal-scan", "scan"},
        {"meshes/lion-head.off", "cgal-scan", "scan"},
        {"points_3/b9_training.ply", "cgal-aerial", "aerial"},
        {"points_3/building.ply", "cgal-aerial", "aerial"},
    };
    fs::path root = fs::path(raw_dir) / "cgal" / "data";
    if (!fs::is_directory(root))
        throw_input_error(root.string(), "missing CGAL data: run scripts/get-data.sh");
    std::vector<SourceModel> models;
    for (const Entry& e : kEntries) {
        if (!fs::exists(root / e.file)) continue;
        SourceModel m;
        m.path = (fs::path("cgal/data") / e.file).string();
        m.id = "cgal/" + fs::path(e.file).stem().string();
        m.source = e.source;
        m.category = e.category;
        m.name = fs::path(e.file).stem().string();
        models.push_back(std::move(m));
    }
    return models;
}

std::string assign_split(const SourceModel& model, double test_fraction, double val_fraction) {
    if (model.human) return "test-humans";
    if (model.source == "cgal-cad") return "train";
    if (model.source == "cgal-scan") return "test-scans";
    if (model.source == "cgal-aerial") return "test-aerial";
    double u = hash_fraction(model.id);
    if (u < test_fraction) return "test-indist";
    if (u < test_fraction + val_fraction) return "val";
    return "train";
}

}  // namespace pumeta
