#pragma once
// Files a run writes: particles as VTK XML unstructured grids (.vtu, one per frame, binary appended data)
// gathered by a .pvd time series that ParaView opens; the energy history as CSV; the run summary as JSON
// (run.hpp). Axisymmetric runs write points as (r, z, 0).

#include <string>
#include <vector>

#include "blt/sim/constitutive.hpp"
#include "blt/sim/particles.hpp"

namespace blt::sim {

// Writes one frame with the particle fields: velocity (m/s), displacement-free state (mass kg, volume m^3,
// density kg/m^3), stress (Pa, full tensor), pressure (Pa), von_mises (Pa), specific_energy (J/kg),
// temperature (K), plastic_strain, damage, failed, active, material, body. Throws std::runtime_error naming the
// path when the file cannot be written.
template <int D>
void writeVtu(const std::string& path, const Particles<D>& particles);

// Keeps the first `lines` lines of a text file and drops the rest: a resumed run's history files lose what the
// interrupted run wrote after its checkpoint. Throws InputError naming the file when it is missing or shorter.
void keepFirstLines(const std::string& path, std::size_t lines);

// A .pvd collection, rewritten whole after each frame so that an interrupted run leaves a valid file.
class PvdSeries {
 public:
  explicit PvdSeries(std::string path) : path_(std::move(path)) {}
  void add(double time, const std::string& fileRelativeToPvd);
  const std::string& path() const { return path_; }
  const std::vector<std::pair<double, std::string>>& frames() const { return frames_; }  // (time s, file), in order

 private:
  std::string path_;
  std::vector<std::pair<double, std::string>> frames_;
};

}  // namespace blt::sim
