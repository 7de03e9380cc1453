// A plain driver for the fuzz targets, for builds without libFuzzer: runs every file named
// on the command line (directories: every file inside, recursively) through the target
// once. ctest replays the seed corpus and the regression inputs with it, so a fixed crash
// stays fixed in the ordinary build; bench/fuzz.sh does the real fuzzing.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace {

bool RunFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    std::cerr << file << ": cannot read\n";
    return false;
  }
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
  LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  int inputs = 0;
  bool ok = true;
  for (int k = 1; k < argc; ++k) {
    const fs::path arg(argv[k]);
    if (fs::is_directory(arg)) {
      for (const auto& e : fs::recursive_directory_iterator(arg)) {
        // Dot files (.gitkeep) hold a directory in git, they are not inputs.
        if (!e.is_regular_file() || e.path().filename().string()[0] == '.') continue;
        ok = RunFile(e.path()) && ok;
        ++inputs;
      }
    } else {
      ok = RunFile(arg) && ok;
      ++inputs;
    }
  }
  std::cout << argv[0] << ": " << inputs << " inputs replayed\n";
  // An empty corpus would make the test pass without testing anything.
  return ok && inputs > 0 ? 0 : 1;
}
