#pragma once
// Material points stored as a structure of arrays: one array per field, so each pass of the solver streams
// only the fields it needs. The arrays are sized when the problem is set up; a step allocates nothing.
//
// Dimension D = 3: Cartesian (x, y, z). D = 2: axisymmetric (r, z); the tensors stay 3x3 with the hoop
// direction theta as the third axis, and volumes and masses are per radian (V = r dr dz).

#include <Eigen/Core>
#include <Eigen/LU>  // determinant of the deformation gradient
#include <cstdint>
#include <vector>

namespace blt::sim {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;
using Mat3 = Eigen::Matrix3d;

// Particles::failed of a point that erosion took out of the material but kept as a stress-free mass point
// (SolverOptions::keepErodedMass).
inline constexpr std::uint8_t kEroded = 2;

template <int D>
struct Particles {
  // Kinematics.
  std::vector<Vec<D>> position;  // m
  std::vector<Vec<D>> velocity;  // m/s
  std::vector<Vec<D>> halfSize;  // m, half the particle's initial extent per axis (uGIMP domain)
  // Mass and volume (per radian in axisymmetric runs).
  std::vector<double> mass;           // kg
  std::vector<double> initialVolume;  // m^3
  std::vector<double> volume;         // m^3, current: initialVolume * det(F)
  std::vector<Mat3> deformationGradient;
  // Material state.
  std::vector<Mat3> stress;             // Pa, Cauchy, tension positive
  std::vector<double> viscousPressure;  // Pa, artificial bulk viscosity q (not part of the stored stress)
  std::vector<double> specificEnergy;   // J/kg, internal energy (elastic + plastic + shock heating)
  std::vector<double> temperature;      // K
  std::vector<double> plasticStrain;    // equivalent plastic strain
  std::vector<double> damage;           // Johnson-Cook damage (0 intact, 1 failed)
  std::vector<double> soundSpeed;       // m/s, from the last stress update (time step control)
  std::vector<double> plasticWork;      // J, accumulated (energy history)
  std::vector<double> viscousWork;      // J, accumulated
  std::vector<std::uint8_t> failed;     // 1 when the failure model has triggered; kEroded: eroded, mass kept
  std::vector<std::uint8_t> active;     // 0 once a particle has left the grid or erosion has removed it
  std::vector<int> material;            // index into the solver's material list
  std::vector<int> body;                // body id (projectile 0, layers 1..); separate nodal fields per body

  std::size_t size() const { return position.size(); }

  void reserve(std::size_t n);
  // Appends one particle at rest in its reference state; returns its index.
  std::size_t add(const Vec<D>& x, const Vec<D>& v, double particleVolume, double density, const Vec<D>& half,
                  int materialId, int bodyId, double roomTemperature);
  // Bytes held by the particle arrays (capacity), for the memory figures of the benchmark.
  std::size_t bytes() const;
  // Reorders every array so that new particle i is old particle order[i] (a permutation). Allocates one
  // scratch array per field; the solver calls it every few dozen steps to keep neighbours close in memory.
  void permute(const std::vector<int>& order);

  // Calls f(array) for every per-particle array, always in the same order (permutation, checkpoints).
  template <class F>
  void forEachArray(F&& f) {
    f(position), f(velocity), f(halfSize), f(mass), f(initialVolume), f(volume), f(deformationGradient);
    f(stress), f(viscousPressure), f(specificEnergy), f(temperature), f(plasticStrain), f(damage);
    f(soundSpeed), f(plasticWork), f(viscousWork), f(failed), f(active), f(material), f(body);
  }
};

}  // namespace blt::sim
