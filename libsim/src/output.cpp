#include "blt/sim/output.hpp"

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "blt/core/error.hpp"

namespace blt::sim {

namespace {

// Appended raw binary: each array is a UInt64 byte count followed by its bytes.
class AppendedData {
 public:
  template <class T>
  std::size_t add(const std::vector<T>& values) {
    const std::size_t offset = bytes_.size();
    const std::uint64_t n = values.size() * sizeof(T);
    append(&n, sizeof n);
    append(values.data(), n);
    return offset;
  }
  const std::string& bytes() const { return bytes_; }

 private:
  void append(const void* p, std::size_t n) { bytes_.append(static_cast<const char*>(p), n); }
  std::string bytes_;
};

struct ArrayInfo {
  std::string name, type;
  int components;
  std::size_t offset;
};

}  // namespace

template <int D>
void writeVtu(const std::string& path, const Particles<D>& particles) {
  const std::size_t n = particles.size();
  AppendedData data;
  std::vector<ArrayInfo> pointData;
  auto vec3 = [&](const std::vector<Vec<D>>& v) {
    std::vector<double> out(3 * n, 0.0);
    for (std::size_t p = 0; p < n; ++p)
      for (int a = 0; a < D; ++a) out[3 * p + a] = v[p][a];
    return out;
  };
  const std::size_t pointsOffset = data.add(vec3(particles.position));
  auto scalar = [&](const std::string& name, auto&& f) {
    std::vector<double> out(n);
    for (std::size_t p = 0; p < n; ++p) out[p] = f(p);
    pointData.push_back({name, "Float64", 1, data.add(out)});
  };
  auto integer = [&](const std::string& name, auto&& f) {
    std::vector<std::int32_t> out(n);
    for (std::size_t p = 0; p < n; ++p) out[p] = static_cast<std::int32_t>(f(p));
    pointData.push_back({name, "Int32", 1, data.add(out)});
  };
  pointData.push_back({"velocity_m_s", "Float64", 3, data.add(vec3(particles.velocity))});
  {
    std::vector<double> s(9 * n);
    for (std::size_t p = 0; p < n; ++p)
      for (int k = 0; k < 9; ++k) s[9 * p + k] = particles.stress[p](k / 3, k % 3);
    pointData.push_back({"stress_Pa", "Float64", 9, data.add(s)});
  }
  scalar("pressure_Pa", [&](std::size_t p) { return -particles.stress[p].trace() / 3.0; });
  scalar("von_mises_Pa", [&](std::size_t p) {
    const Mat3 s = particles.stress[p] - (particles.stress[p].trace() / 3.0) * Mat3::Identity();
    return std::sqrt(1.5 * s.cwiseProduct(s).sum());
  });
  scalar("mass_kg", [&](std::size_t p) { return particles.mass[p]; });
  scalar("volume_m3", [&](std::size_t p) { return particles.volume[p]; });
  scalar("density_kg_m3", [&](std::size_t p) { return particles.mass[p] / particles.volume[p]; });
  scalar("specific_energy_J_kg", [&](std::size_t p) { return particles.specificEnergy[p]; });
  scalar("temperature_K", [&](std::size_t p) { return particles.temperature[p]; });
  scalar("plastic_strain", [&](std::size_t p) { return particles.plasticStrain[p]; });
  scalar("damage", [&](std::size_t p) { return particles.damage[p]; });
  integer("failed", [&](std::size_t p) { return particles.failed[p]; });
  integer("active", [&](std::size_t p) { return particles.active[p]; });
  integer("material", [&](std::size_t p) { return particles.material[p]; });
  integer("body", [&](std::size_t p) { return particles.body[p]; });
  // One VTK_VERTEX cell per particle.
  std::vector<std::int64_t> connectivity(n), offsets(n);
  std::vector<std::uint8_t> types(n, 1);
  for (std::size_t p = 0; p < n; ++p) {
    connectivity[p] = static_cast<std::int64_t>(p);
    offsets[p] = static_cast<std::int64_t>(p + 1);
  }
  const std::size_t connOffset = data.add(connectivity);
  const std::size_t offOffset = data.add(offsets);
  const std::size_t typeOffset = data.add(types);

  std::ostringstream xml;
  xml << "<?xml version=\"1.0\"?>\n"
      << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
      << "<UnstructuredGrid>\n<Piece NumberOfPoints=\"" << n << "\" NumberOfCells=\"" << n << "\">\n"
      << "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\""
      << pointsOffset << "\"/>\n</Points>\n<PointData>\n";
  for (const auto& a : pointData)
    xml << "<DataArray type=\"" << a.type << "\" Name=\"" << a.name << "\" NumberOfComponents=\"" << a.components
        << "\" format=\"appended\" offset=\"" << a.offset << "\"/>\n";
  xml << "</PointData>\n<Cells>\n"
      << "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\" offset=\"" << connOffset << "\"/>\n"
      << "<DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\" offset=\"" << offOffset << "\"/>\n"
      << "<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"" << typeOffset << "\"/>\n"
      << "</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_";
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << xml.str();
  out.write(data.bytes().data(), static_cast<std::streamsize>(data.bytes().size()));
  out << "\n</AppendedData>\n</VTKFile>\n";
  if (!out) throw std::runtime_error("failed writing " + path);
}

template void writeVtu<2>(const std::string&, const Particles<2>&);
template void writeVtu<3>(const std::string&, const Particles<3>&);

void keepFirstLines(const std::string& path, std::size_t lines) {
  std::ifstream in(path);
  if (!in) throw InputError(InputLocation::file(path), "cannot read it to go on from a checkpoint", "the file the run wrote");
  std::string kept, line;
  std::size_t count = 0;
  while (count < lines && std::getline(in, line)) {
    kept += line;
    kept += '\n';
    ++count;
  }
  in.close();
  if (count < lines)
    throw InputError(InputLocation::file(path),
                     "holds " + std::to_string(count) + " lines, the checkpoint says " + std::to_string(lines),
                     "the file of the run that wrote the checkpoint");
  const std::string tmp = path + ".tmp";  // a kill while rewriting leaves the old file whole
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << kept;
    if (!out) throw std::runtime_error("cannot write " + tmp);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) throw std::runtime_error("cannot write " + path);
}

void PvdSeries::add(double time, const std::string& file) {
  frames_.emplace_back(time, file);
  const std::string tmp = path_ + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) throw std::runtime_error("cannot write " + tmp);
    out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
    out.precision(12);
    for (const auto& [t, f] : frames_)
      out << "<DataSet timestep=\"" << t << "\" group=\"\" part=\"0\" file=\"" << f << "\"/>\n";
    out << "</Collection>\n</VTKFile>\n";
  }
  if (std::rename(tmp.c_str(), path_.c_str()) != 0) throw std::runtime_error("cannot write " + path_);
}

}  // namespace blt::sim
