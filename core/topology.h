// Communication topology of the followers and the leader (paper Sec. II-A).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

namespace shoal {

/// Directed graph over followers 1..n plus the leader 0.
/// a_ij = 1 if follower i receives from follower j (edge (i, j) in the scenario);
/// D = diag(a_i0) with a_i0 = 1 if follower i receives the leader.
/// L = [l_ij], l_ii = sum_j a_ij, l_ij = -a_ij;  H = L + D  (paper eq. (12)).
class Topology {
 public:
  /// Builds the graph; ids are 1-based. Does not validate (see Validate()).
  static Topology Build(int n, const std::vector<std::pair<int, int>>& edges,
                        const std::vector<int>& leader_links);

  int n() const { return n_; }
  /// Adjacency a_ij (0-based indices i-1, j-1).
  const Eigen::MatrixXd& A() const { return a_; }
  /// Pinning matrix D = diag(a_i0).
  Eigen::MatrixXd D() const { return d_.asDiagonal(); }
  Eigen::MatrixXd L() const;
  Eigen::MatrixXd H() const { return L() + D(); }

  /// Followers (1-based) that follower i receives from.
  const std::vector<int>& Neighbours(int i) const { return neighbours_[i - 1]; }
  /// True if follower i receives the leader.
  bool Pinned(int i) const { return d_(i - 1) > 0.0; }
  /// Every directed link (sender, receiver), the leader's links first, then follower
  /// links in receiver order: the set of links the channel emulator serves.
  std::vector<std::pair<int, int>> Links() const;

  /// Assumption 1: every follower is reachable from the leader through directed links.
  /// Returns the 1-based ids of the followers the leader cannot reach (empty if it holds).
  std::vector<int> UnreachableFollowers() const;

 private:
  int n_ = 0;
  Eigen::MatrixXd a_;
  Eigen::VectorXd d_;
  std::vector<std::vector<int>> neighbours_;
};

}  // namespace shoal
