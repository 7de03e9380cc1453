// Tests of core/topology: the paper's graph (Fig. 1) gives the printed L, D and
// eig(H); Links() lists the directed links; Assumption 1 (every follower reachable
// from the leader) is checked, and agrees with the spectral characterisation
// (H = L + D nonsingular with all eigenvalues in the open right half-plane) on random
// graphs.
#include "core/topology.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <complex>
#include <utility>
#include <vector>

#include "core/rng.h"

namespace shoal {
namespace {

Topology PaperTopology() {
  return Topology::Build(5, {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}}, {1, 3, 5});
}

std::vector<std::complex<double>> Eigenvalues(const Eigen::MatrixXd& m) {
  Eigen::EigenSolver<Eigen::MatrixXd> es(m, /*computeEigenvectors=*/false);
  std::vector<std::complex<double>> out;
  for (int i = 0; i < es.eigenvalues().size(); ++i) out.push_back(es.eigenvalues()(i));
  return out;
}

TEST(TopologyTest, PaperLaplacianAndPinningMatrix) {
  const Topology t = PaperTopology();
  ASSERT_EQ(t.n(), 5);
  Eigen::MatrixXd L(5, 5);
  L << 1, 0, -1, 0, 0,   //
      -1, 2, 0, 0, -1,   //
      -1, 0, 1, 0, 0,    //
      0, 0, 0, 1, -1,    //
      0, -1, 0, -1, 2;
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(5, 5);
  D.diagonal() << 1, 0, 1, 0, 1;
  EXPECT_EQ(t.L(), L) << "\n" << t.L();
  EXPECT_EQ(t.D(), D) << "\n" << t.D();
  EXPECT_EQ(t.H(), L + D);
  // Rows of L sum to zero; A is L's negated off-diagonal.
  EXPECT_EQ(t.L().rowwise().sum().cwiseAbs().maxCoeff(), 0.0);
  Eigen::MatrixXd A = -L;
  A.diagonal().setZero();
  EXPECT_EQ(t.A(), A);
}

TEST(TopologyTest, PaperEigenvaluesOfH) {
  auto eig = Eigenvalues(PaperTopology().H());
  ASSERT_EQ(eig.size(), 5u);
  for (const auto& e : eig) EXPECT_NEAR(e.imag(), 0.0, 1e-9) << e;
  std::sort(eig.begin(), eig.end(),
            [](const auto& a, const auto& b) { return a.real() > b.real(); });
  const double printed[5] = {3.879, 3.0, 1.653, 1.0, 0.468};
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(eig[i].real(), printed[i], 1e-3) << i;
}

TEST(TopologyTest, PaperNeighboursPinningAndLinks) {
  const Topology t = PaperTopology();
  EXPECT_EQ(t.Neighbours(1), std::vector<int>{3});
  EXPECT_EQ(t.Neighbours(2), (std::vector<int>{1, 5}));
  EXPECT_EQ(t.Neighbours(3), std::vector<int>{1});
  EXPECT_EQ(t.Neighbours(4), std::vector<int>{5});
  EXPECT_EQ(t.Neighbours(5), (std::vector<int>{2, 4}));
  EXPECT_TRUE(t.Pinned(1));
  EXPECT_FALSE(t.Pinned(2));
  EXPECT_TRUE(t.Pinned(3));
  EXPECT_FALSE(t.Pinned(4));
  EXPECT_TRUE(t.Pinned(5));
  // (sender, receiver): the leader's links first, then follower links by receiver.
  const std::vector<std::pair<int, int>> links = {{0, 1}, {0, 3}, {0, 5}, {3, 1}, {1, 2},
                                                  {5, 2}, {1, 3}, {5, 4}, {2, 5}, {4, 5}};
  EXPECT_EQ(t.Links(), links);
  EXPECT_EQ(t.Links().size(), 10u);
  EXPECT_TRUE(t.UnreachableFollowers().empty());
}

TEST(TopologyTest, BuildIgnoresInvalidAndDuplicateEdges) {
  const Topology t =
      Topology::Build(3, {{2, 1}, {2, 1}, {3, 3}, {0, 1}, {4, 1}, {3, 2}, {1, 9}}, {1, 7, 0});
  EXPECT_EQ(t.Neighbours(2), std::vector<int>{1});
  EXPECT_TRUE(t.Neighbours(1).empty());
  EXPECT_EQ(t.Neighbours(3), std::vector<int>{2});
  EXPECT_EQ(t.A().sum(), 2.0);
  EXPECT_EQ(t.D().sum(), 1.0);
  EXPECT_EQ(t.Links(), (std::vector<std::pair<int, int>>{{0, 1}, {1, 2}, {2, 3}}));
  EXPECT_TRUE(t.UnreachableFollowers().empty());
}

TEST(TopologyTest, UnreachableFollowersAreNamed) {
  // A follower with no in-edges.
  EXPECT_EQ(Topology::Build(3, {{2, 1}}, {1}).UnreachableFollowers(), std::vector<int>{3});
  // A pair that only hears each other.
  EXPECT_EQ(Topology::Build(4, {{2, 1}, {3, 4}, {4, 3}}, {1}).UnreachableFollowers(),
            (std::vector<int>{3, 4}));
  // Edge direction matters: 1 hears 2, but 2 hears nobody.
  EXPECT_EQ(Topology::Build(2, {{1, 2}}, {1}).UnreachableFollowers(), std::vector<int>{2});
  // Only through an unreachable follower: 3 hears 2, 2 hears nobody.
  EXPECT_EQ(Topology::Build(3, {{3, 2}}, {1}).UnreachableFollowers(), (std::vector<int>{2, 3}));
  // No leader links: nobody.
  EXPECT_EQ(Topology::Build(3, {{2, 1}, {3, 2}, {1, 3}}, {}).UnreachableFollowers(),
            (std::vector<int>{1, 2, 3}));
  // The paper's graph without its leader link to 1 still holds (1 hears 3);
  // without the links to 3 and 5 as well nobody is reached.
  EXPECT_TRUE(Topology::Build(5, {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}}, {3, 5})
                  .UnreachableFollowers()
                  .empty());
  EXPECT_EQ(Topology::Build(5, {{1, 3}, {2, 1}, {2, 5}, {3, 1}, {4, 5}, {5, 2}, {5, 4}}, {1})
                .UnreachableFollowers(),
            (std::vector<int>{}));
  EXPECT_EQ(Topology::Build(5, {{1, 3}, {2, 1}, {3, 1}, {4, 5}, {5, 4}}, {1})
                .UnreachableFollowers(),
            (std::vector<int>{4, 5}));
}

TEST(TopologyTest, ReachabilityAgreesWithSpectrumOfH) {
  // Independent characterisation: every follower is reachable from the leader iff
  // H = L + D is nonsingular, and then every eigenvalue has a positive real part.
  // det(H) is an integer here, so |det| < 0.5 means singular.
  Rng rng(2718);
  int holds = 0, fails = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const int n = 2 + static_cast<int>(rng.Uniform() * 7);  // 2..8
    const double p = 0.1 + 0.3 * rng.Uniform();
    std::vector<std::pair<int, int>> edges;
    for (int i = 1; i <= n; ++i)
      for (int j = 1; j <= n; ++j)
        if (i != j && rng.Uniform() < p) edges.emplace_back(i, j);
    std::vector<int> leader_links;
    for (int i = 1; i <= n; ++i)
      if (rng.Uniform() < 0.2) leader_links.push_back(i);
    const Topology t = Topology::Build(n, edges, leader_links);
    const Eigen::MatrixXd H = t.H();
    const bool reachable = t.UnreachableFollowers().empty();
    const double det = H.determinant();
    ASSERT_EQ(std::abs(det) >= 0.5, reachable) << "trial " << trial << " det " << det << "\n" << H;
    if (reachable) {
      ++holds;
      for (const auto& e : Eigenvalues(H)) ASSERT_GT(e.real(), 1e-9) << "trial " << trial;
    } else {
      ++fails;
      // The named followers are exactly those with no directed path from the leader:
      // each unreachable follower hears only unreachable followers and is not pinned.
      const std::vector<int> u = t.UnreachableFollowers();
      for (int i : u) {
        ASSERT_FALSE(t.Pinned(i));
        for (int j : t.Neighbours(i))
          ASSERT_TRUE(std::find(u.begin(), u.end(), j) != u.end()) << i << " hears " << j;
      }
    }
    ASSERT_EQ(t.Links().size(), static_cast<std::size_t>(t.A().sum() + t.D().sum()));
  }
  EXPECT_GT(holds, 200);
  EXPECT_GT(fails, 200);
}

}  // namespace
}  // namespace shoal
