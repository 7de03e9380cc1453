#include "core/topology.h"

#include <deque>

namespace shoal {

Topology Topology::Build(int n, const std::vector<std::pair<int, int>>& edges,
                         const std::vector<int>& leader_links) {
  Topology t;
  t.n_ = n;
  t.a_ = Eigen::MatrixXd::Zero(n, n);
  t.d_ = Eigen::VectorXd::Zero(n);
  t.neighbours_.assign(n, {});
  for (const auto& [i, j] : edges) {
    if (i < 1 || i > n || j < 1 || j > n || i == j) continue;
    if (t.a_(i - 1, j - 1) == 0.0) t.neighbours_[i - 1].push_back(j);
    t.a_(i - 1, j - 1) = 1.0;
  }
  for (int i : leader_links) {
    if (i >= 1 && i <= n) t.d_(i - 1) = 1.0;
  }
  return t;
}

Eigen::MatrixXd Topology::L() const {
  Eigen::MatrixXd l = -a_;
  for (int i = 0; i < n_; ++i) l(i, i) = a_.row(i).sum();
  return l;
}

std::vector<std::pair<int, int>> Topology::Links() const {
  std::vector<std::pair<int, int>> links;
  for (int i = 1; i <= n_; ++i) {
    if (Pinned(i)) links.emplace_back(0, i);
  }
  for (int i = 1; i <= n_; ++i) {
    for (int j : neighbours_[i - 1]) links.emplace_back(j, i);
  }
  return links;
}

std::vector<int> Topology::UnreachableFollowers() const {
  // Breadth-first search along information flow: leader -> pinned, j -> i if a_ij > 0.
  std::vector<bool> reached(n_, false);
  std::deque<int> queue;
  for (int i = 0; i < n_; ++i) {
    if (d_(i) > 0.0) {
      reached[i] = true;
      queue.push_back(i);
    }
  }
  while (!queue.empty()) {
    const int j = queue.front();
    queue.pop_front();
    for (int i = 0; i < n_; ++i) {
      if (!reached[i] && a_(i, j) > 0.0) {
        reached[i] = true;
        queue.push_back(i);
      }
    }
  }
  std::vector<int> out;
  for (int i = 0; i < n_; ++i) {
    if (!reached[i]) out.push_back(i + 1);
  }
  return out;
}

}  // namespace shoal
