// The backbone registry: name -> factory and small config. The library is static, so
// registration happens in register_builtin_backbones(), called once on first use, not from
// static initialisers (which the linker would drop along with unreferenced object files).
#include <map>
#include <mutex>

#include "pumeta/core/error.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/dispu.h"
#include "pumeta/models/gradpu.h"
#include "pumeta/models/metapu.h"
#include "pumeta/models/mpu.h"
#include "pumeta/models/pudense.h"
#include "pumeta/models/pugan.h"
#include "pumeta/models/pugaussian.h"
#include "pumeta/models/pugcn.h"

namespace pumeta {

namespace {

std::mutex& registry_mutex() {
    static std::mutex mutex;
    return mutex;
}

struct Registration {
    BackboneFactory factory;
    nlohmann::json small_config;
};

std::map<std::string, Registration>& registry() {
    static std::map<std::string, Registration> kinds;
    return kinds;
}

void register_builtin_backbones() {
    register_backbone("pugcn", make_pugcn, pugcn_small_config());
    register_backbone("dispu", make_dispu, dispu_small_config());
    register_backbone("pudense", make_pudense, pudense_small_config());
    register_backbone("metapu", make_metapu, metapu_small_config());
    register_backbone("pugan", make_pugan, pugan_small_config());
    register_backbone("mpu", make_mpu, mpu_small_config());
    register_backbone("gradpu", make_gradpu, gradpu_small_config());
    register_backbone("pugaussian", make_pugaussian, pugaussian_small_config());
}

void ensure_builtins_registered() {
    static std::once_flag once;
    std::call_once(once, register_builtin_backbones);
}

}  // namespace

void register_backbone(const std::string& name, BackboneFactory factory,
                       nlohmann::json small_config) {
    if (!small_config.is_null() &&
        (!small_config.is_object() || !small_config.contains("backbone") ||
         small_config["backbone"] != name))
        throw InternalError("small config of backbone '" + name + "' is not {\"backbone\": \"" +
                            name + "\", ...}: " + small_config.dump());
    std::lock_guard<std::mutex> lock(registry_mutex());
    if (!registry().emplace(name, Registration{std::move(factory), std::move(small_config)}).second)
        throw InternalError("backbone '" + name + "' registered twice");
}

std::vector<std::string> registered_backbones() {
    ensure_builtins_registered();
    std::lock_guard<std::mutex> lock(registry_mutex());
    std::vector<std::string> names;
    for (const auto& entry : registry()) names.push_back(entry.first);
    return names;
}

nlohmann::json small_backbone_config(const std::string& name) {
    ensure_builtins_registered();
    std::lock_guard<std::mutex> lock(registry_mutex());
    auto it = registry().find(name);
    if (it == registry().end()) throw_input_error("backbone", "unknown backbone '{}'", name);
    return it->second.small_config;
}

std::unique_ptr<Backbone> make_backbone(const nlohmann::json& config) {
    ensure_builtins_registered();
    if (!config.is_object() || !config.contains("backbone") || !config["backbone"].is_string())
        throw_input_error("backbone config", "expected an object with a \"backbone\" name");
    const std::string name = config["backbone"].get<std::string>();
    BackboneFactory factory;
    {
        std::lock_guard<std::mutex> lock(registry_mutex());
        auto it = registry().find(name);
        if (it == registry().end()) {
            std::string known;
            for (const auto& entry : registry()) known += (known.empty() ? "" : ", ") + entry.first;
            throw_input_error("backbone config", "unknown backbone '{}' (known: {})", name, known);
        }
        factory = it->second.factory;
    }
    return factory(config);
}

}  // namespace pumeta
