// Counts the distinct 64-byte cache lines one process touches between two executions of
// one instruction, from a valgrind lackey trace (--trace-mem=yes) on stdin: with the
// instruction at the entry of a vehicle's ClockedNode::HandleBus, the user-space data and
// code lines of each lockstep window. These are what the window must fetch again when a
// hundred other processes have run on its CPU since its last turn and its lines have left
// that CPU's L2; the count does not depend on the machine or on what else runs. The pages
// are what the window's address translations cover: each costs a walk of the page tables
// when the TLB no longer holds the process's entries.
// Usage: window_lines MARK_HEX [SKIP [CODE_OUT]] < trace
//   prints one row per window: window, data lines, code lines, data pages, code pages
//   (SKIP first windows, default 20: the start-up's), then the medians on stderr. With
//   CODE_OUT, also writes there, one per line in hexadecimal, the address of every instruction
//   the counted windows ran, in the order they first ran it (bench/window_code.sh).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <unordered_set>
#include <vector>

namespace {
// The instructions of the counted windows in the order they first ran (by address: a
// function of a few bytes can share its line with another). Those of a window are kept only
// once it is complete (the mark ran again), so the exit's code, after the last window, is
// not among them.
struct CodeOrder {
  std::unordered_set<unsigned long> seen, window_seen;
  std::vector<unsigned long> order, window;

  void Ran(unsigned long ip) {
    if (window_seen.insert(ip).second) window.push_back(ip);
  }
  void WindowDone(bool counted) {
    if (counted) {
      for (unsigned long ip : window) {
        if (seen.insert(ip).second) order.push_back(ip);
      }
    }
    window.clear();
    window_seen.clear();
  }
};

std::size_t Median(std::vector<std::size_t> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: window_lines MARK_HEX [SKIP [CODE_OUT]] < lackey-trace\n");
    return 2;
  }
  const unsigned long mark = std::strtoul(argv[1], nullptr, 16);
  const long skip = argc > 2 ? std::atol(argv[2]) : 20;
  const char* code_out = argc > 3 ? argv[3] : nullptr;
  CodeOrder code_order;
  std::unordered_set<unsigned long> data, code, pages, code_pages;
  std::vector<std::size_t> data_n, code_n, pages_n, code_pages_n;
  char line[256];
  long window = -1;
  while (std::fgets(line, sizeof line, stdin) != nullptr) {
    char* end = nullptr;
    if (line[0] == 'I' && line[1] == ' ') {
      const unsigned long ip = std::strtoul(line + 3, &end, 16);
      if (ip == mark) {
        if (window >= skip) {
          std::printf("%ld %zu %zu %zu %zu\n", window, data.size(), code.size(), pages.size(),
                      code_pages.size());
          data_n.push_back(data.size());
          code_n.push_back(code.size());
          pages_n.push_back(pages.size());
          code_pages_n.push_back(code_pages.size());
        }
        code_order.WindowDone(window >= skip);
        ++window;
        data.clear();
        code.clear();
        pages.clear();
        code_pages.clear();
      }
      code.insert(ip >> 6);
      code_pages.insert(ip >> 12);
      if (code_out != nullptr) code_order.Ran(ip);
    } else if (line[0] == ' ' && (line[1] == 'L' || line[1] == 'S' || line[1] == 'M')) {
      const unsigned long a = std::strtoul(line + 3, &end, 16);
      const long size = end != nullptr && *end == ',' ? std::strtol(end + 1, nullptr, 10) : 1;
      for (unsigned long l = a >> 6; l <= (a + static_cast<unsigned long>(size) - 1) >> 6; ++l) {
        data.insert(l);
        pages.insert(l >> 6);
      }
    }
  }
  if (data_n.empty()) {
    std::fprintf(stderr, "window_lines: no window: instruction %lx was executed %ld time(s)\n",
                 mark, window + 1);
    return 1;
  }
  if (code_out != nullptr) {
    FILE* f = std::fopen(code_out, "w");
    if (f == nullptr) {
      std::perror(code_out);
      return 1;
    }
    for (unsigned long ip : code_order.order) std::fprintf(f, "%lx\n", ip);
    if (std::fclose(f) != 0) {
      std::perror(code_out);
      return 1;
    }
  }
  std::fprintf(stderr,
               "windows %zu  median per window: data lines %zu, code lines %zu, data pages %zu, "
               "code pages %zu\n",
               data_n.size(), Median(data_n), Median(code_n), Median(pages_n),
               Median(code_pages_n));
  return 0;
}
