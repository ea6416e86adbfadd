#include "calculix_io.hpp"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace ultrasim::sim::test {

namespace {

std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

std::string calculix_input(const CalculixProblem& problem) {
  const auto& mesh = *problem.mesh;
  std::ostringstream out;
  out << "** ultrasim: identical problem for CalculiX (mm, kPa, mN)\n*NODE, NSET=NALL\n";
  for (int n = 0; n < mesh.node_count(); ++n) {
    const auto& p = mesh.rest_positions_mm[n];
    out << n + 1 << ", " << number(p.x()) << ", " << number(p.y()) << ", " << number(p.z()) << "\n";
  }
  // Group tets by material (E, ν, name): one ELSET and section per group.
  using Key = std::tuple<double, double, std::string>;
  std::map<Key, std::vector<int>> groups;
  for (int t = 0; t < mesh.tet_count(); ++t) {
    const auto& m = problem.tet_materials[t];
    groups[Key{m.youngs_modulus_kpa, m.poisson_ratio, m.name}].push_back(t);
  }
  int group = 0;
  for (const auto& [key, tets] : groups) {
    out << "*ELEMENT, TYPE=C3D4, ELSET=E" << group << "\n";
    for (int t : tets) {
      const auto& tet = mesh.tets[t];
      out << t + 1 << ", " << tet[0] + 1 << ", " << tet[1] + 1 << ", " << tet[2] + 1 << ", "
          << tet[3] + 1 << "\n";
    }
    out << "*MATERIAL, NAME=M" << group << "\n*ELASTIC\n"
        << number(std::get<0>(key)) << ", " << number(std::get<1>(key)) << "\n";
    out << "*SOLID SECTION, ELSET=E" << group << ", MATERIAL=M" << group << "\n";
    ++group;
  }
  out << "*BOUNDARY\n";
  for (int n = 0; n < mesh.node_count(); ++n) {
    if (problem.fixed_nodes[n]) out << n + 1 << ", 1, 3\n";
  }
  out << "*STEP\n*STATIC\n";
  if (!problem.held.empty()) {
    out << "*BOUNDARY\n";
    for (const auto& h : problem.held) {
      for (int i = 0; i < 3; ++i) {
        out << h.node + 1 << ", " << i + 1 << ", " << i + 1 << ", " << number(h.displacement_mm[i])
            << "\n";
      }
    }
  }
  if (!problem.loads.empty()) {
    out << "*CLOAD\n";
    for (const auto& l : problem.loads) {
      for (int i = 0; i < 3; ++i) {
        if (l.force_mn[i] != 0.0)
          out << l.node + 1 << ", " << i + 1 << ", " << number(l.force_mn[i]) << "\n";
      }
    }
  }
  out << "*NODE PRINT, NSET=NALL\nU\n*END STEP\n";
  return out.str();
}

std::vector<Eigen::Vector3d> parse_calculix_displacements(const std::string& dat_text,
                                                          int node_count) {
  const auto header = dat_text.find("displacements (vx,vy,vz)");
  if (header == std::string::npos) {
    throw std::runtime_error("ccx .dat has no 'displacements (vx,vy,vz)' block");
  }
  std::istringstream in(dat_text.substr(dat_text.find('\n', header) + 1));
  std::vector<Eigen::Vector3d> u(node_count, Eigen::Vector3d::Constant(std::nan("")));
  std::vector<std::uint8_t> seen(node_count, 0);
  std::string line;
  int found = 0;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    int node = 0;
    double x = 0, y = 0, z = 0;
    if (!(fields >> node >> x >> y >> z)) {
      if (found > 0) break;  // blank line or next block after the data
      continue;
    }
    if (node < 1 || node > node_count) throw std::runtime_error("ccx .dat: node out of range");
    u[node - 1] = Eigen::Vector3d(x, y, z);
    found += seen[node - 1] ? 0 : 1;
    seen[node - 1] = 1;
  }
  if (found != node_count) {
    throw std::runtime_error("ccx .dat: " + std::to_string(found) + " of " +
                             std::to_string(node_count) + " nodes' displacements found");
  }
  return u;
}

bool calculix_available() {
  return std::system("command -v ccx > /dev/null 2>&1") == 0;
}

std::vector<Eigen::Vector3d> solve_with_calculix(const CalculixProblem& problem) {
  std::random_device seed;
  const auto dir = std::filesystem::temp_directory_path() /
                   ("ultrasim_ccx_" + std::to_string(seed()) + std::to_string(seed()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream inp(dir / "job.inp");
    inp << calculix_input(problem);
  }
  const std::string command = "cd '" + dir.string() + "' && ccx -i job > ccx.log 2>&1";
  if (std::system(command.c_str()) != 0) {
    const std::string log = read_text(dir / "ccx.log");
    throw std::runtime_error("ccx failed in " + dir.string() + ":\n" +
                             log.substr(log.size() > 2000 ? log.size() - 2000 : 0));
  }
  auto u = parse_calculix_displacements(read_text(dir / "job.dat"), problem.mesh->node_count());
  std::filesystem::remove_all(dir);
  return u;
}

}  // namespace ultrasim::sim::test
