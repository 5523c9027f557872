#pragma once
// The material library: one TOML file per material under data/materials/, each naming its source (seed and
// table). Values carry units ("2770 kg/m3", "265 MPa"); plain numbers are dimensionless. The file format is
// described in data/materials/README.md. Every parameter is checked against the schema of its section's
// model when the file is loaded, so a typo or a wrong unit is reported with file, line and key.
//
// A material is composed of sections, each a small model: [elastic], [strength] (johnson-cook,
// modified-johnson-cook, bilinear, elastic, johnson-holmquist-1, fluid), [eos] (mie-grueneisen, polynomial),
// [failure] (max-principal-stress, max-principal-strain, johnson-cook-damage, johnson-holmquist-1), [thermal],
// [properties] (quasi-static figures used by analytical models). The schema table in materials.cpp is the
// authority; data/materials/README.md lists the keys with their dimensions.

#include <map>
#include <string>
#include <vector>

#include "blt/core/error.hpp"

namespace blt {

struct MaterialSection {
  std::string model;                     // "johnson-cook", "mie-grueneisen", ...; empty for elastic/thermal
  std::map<std::string, double> params;  // SI values
  std::map<std::string, int> lines;      // line of each parameter in the file, for error messages
};

struct Material {
  std::string id;      // file stem, used to refer to the material ("al_2a12")
  std::string name;    // human name ("2A12 aluminium alloy")
  std::string source;  // provenance ("seed 000 Table 3")
  std::string notes;   // assumptions made in transcribing it (e.g. a room temperature the seed does not give)
  std::string path;    // file it was read from
  double density = 0;  // kg/m^3
  std::map<std::string, MaterialSection> sections;

  bool has(const std::string& section) const { return sections.count(section) != 0; }
  bool has(const std::string& section, const std::string& key) const;
  // Throws InputError naming the file and "section.key" when absent.
  const MaterialSection& section(const std::string& section) const;
  double param(const std::string& section, const std::string& key) const;
};

// Reads one material file and checks it against the schema. Throws InputError.
Material loadMaterial(const std::string& path);
// Parses material TOML text; `sourceName` stands for the path in messages.
Material parseMaterial(const std::string& text, const std::string& sourceName, const std::string& id);
// Writes a material back to TOML text (values in SI with units), e.g. a card derived by the laminate model.
std::string materialToToml(const Material& material);

class MaterialLibrary {
 public:
  // data/materials of this checkout, or $BLT_MATERIALS_DIR when set.
  static std::string defaultDirectory();
  // Loads every *.toml file of a directory that describes a material (files with a top-level 'density').
  static MaterialLibrary load(const std::string& directory = defaultDirectory());

  // Throws InputError listing the ids present. On a temporary library (MaterialLibrary::load().get(id)) the
  // material is returned by value, so no reference outlives the library.
  const Material& get(const std::string& id) const&;
  Material get(const std::string& id) &&;
  std::vector<std::string> ids() const;
  size_t size() const { return materials_.size(); }

 private:
  std::string directory_;
  std::map<std::string, Material> materials_;
};

}  // namespace blt
