#pragma once
// Material cards shared by the solver tests.

// Linear elastic solid (aluminium-like): E = 70 GPa, nu = 0.3, rho = 2700 kg/m3.
inline constexpr const char* kElasticAluminium = R"toml(name = "elastic"
source = "test"
density = "2700 kg/m3"
[elastic]
youngs_modulus = "70 GPa"
poisson_ratio = 0.3
[strength]
model = "elastic"
)toml";
