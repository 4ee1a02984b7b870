// The backbone registry: name -> factory. The library is static, so registration happens in
// register_builtin_backbones(), called once on first use, not from static initialisers
// (which the linker would drop along with unreferenced object files).
#include <map>
#include <mutex>

#include "pumeta/core/error.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/dispu.h"
#include "pumeta/models/pudense.h"
#include "pumeta/models/pugcn.h"

namespace pumeta {

namespace {

std::mutex& registry_mutex() {
    static std::mutex mutex;
    return mutex;
}

std::map<std::string, BackboneFactory>& registry() {
    static std::map<std::string, BackboneFactory> factories;
    return factories;
}

void register_builtin_backbones() {
    register_backbone("pugcn", make_pugcn);
    register_backbone("dispu", make_dispu);
    register_backbone("pudense", make_pudense);
}

void ensure_builtins_registered() {
    static std::once_flag once;
    std::call_once(once, register_builtin_backbones);
}

}  // namespace

void register_backbone(const std::string& name, BackboneFactory factory) {
    std::lock_guard<std::mutex> lock(registry_mutex());
    if (!registry().emplace(name, std::move(factory)).second)
        throw InternalError("backbone '" + name + "' registered twice");
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
        factory = it->second;
    }
    return factory(config);
}

}  // namespace pumeta
