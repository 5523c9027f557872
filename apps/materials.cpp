// blt materials: lists the material library and shows one card with its source.
#include "blt/core/materials.hpp"

#include "blt/core/units.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {
nlohmann::json materialJson(const Material& m) {
  nlohmann::json j{{"id", m.id}, {"name", m.name}, {"source", m.source}, {"density_kg_m3", m.density}};
  if (!m.notes.empty()) j["notes"] = m.notes;
  for (const auto& [secName, sec] : m.sections) {
    nlohmann::json s;
    if (!sec.model.empty()) s["model"] = sec.model;
    for (const auto& [k, v] : sec.params) s[k] = v;  // SI
    j[secName] = s;
  }
  return j;
}
}  // namespace

void registerMaterialsCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("materials", "List the material library (data/materials) or show one material");
  auto id = std::make_shared<std::string>();
  auto dir = std::make_shared<std::string>(MaterialLibrary::defaultDirectory());
  auto json = std::make_shared<bool>(false);
  cmd->add_option("id", *id, "Material to show (file name without .toml); all when omitted");
  cmd->add_option("--dir", *dir, "Material directory")->capture_default_str();
  addJsonFlag(*cmd, *json);
  cmd->callback([id, dir, json] {
    const MaterialLibrary lib = MaterialLibrary::load(*dir);
    if (!id->empty()) {
      const Material& m = lib.get(*id);
      if (*json) {
        printJson(materialJson(m));
      } else {
        std::cout << "# " << m.id << " (" << m.path << ")\n" << materialToToml(m);
      }
      return;
    }
    if (*json) {
      nlohmann::json all = nlohmann::json::array();
      for (const auto& mid : lib.ids()) all.push_back(materialJson(lib.get(mid)));
      printJson(all);
      return;
    }
    for (const auto& mid : lib.ids()) {
      const Material& m = lib.get(mid);
      std::printf("%-22s %-40s %10s  %s\n", m.id.c_str(), m.name.c_str(), units::format(m.density, "kg/m3", 5).c_str(),
                  m.source.c_str());
    }
  });
}

}  // namespace blt::cli
