#include "cluster/cluster_edit.h"

#include <gtest/gtest.h>

#include "util/error.h"

namespace nbtf {
namespace {

// Ten texels in a 2-D PCA space: cluster 0 holds two well separated blobs (three texels near
// (0, 0), two near (10, 0)), cluster 1 four texels near (0, 10), cluster 2 one texel.
MatrixXfCol handMadeScores() {
  MatrixXfCol s(10, 2);
  s << 0, 0, 0.1f, 0, 0, 0.1f, 10, 0, 10.1f, 0,  //
      0, 10, 0.1f, 10, 0, 10.1f, 0.1f, 10.1f,  //
      5, 5;
  return s;
}
std::vector<std::int32_t> handMadeIds() { return {0, 0, 0, 0, 0, 1, 1, 1, 1, 2}; }

TEST(ClusterEdit, SplitSeparatesTheBlobsAndTheLargerChildKeepsTheId) {
  MatrixXfCol s = handMadeScores();
  std::vector<std::int32_t> ids = handMadeIds();
  ASSERT_TRUE(splitCluster(s, ids, 0, 3, 7));
  EXPECT_EQ(ids, (std::vector<std::int32_t>{0, 0, 0, 3, 3, 1, 1, 1, 1, 2}));
  // Deterministic, and any seed finds these two blobs.
  std::vector<std::int32_t> again = handMadeIds();
  ASSERT_TRUE(splitCluster(s, again, 0, 3, 99));
  EXPECT_EQ(again, ids);
}

TEST(ClusterEdit, SingletonsAndIdenticalPointsAreNotSplit) {
  MatrixXfCol s = handMadeScores();
  std::vector<std::int32_t> ids = handMadeIds();
  EXPECT_FALSE(splitCluster(s, ids, 2, 3, 1));
  EXPECT_EQ(ids, handMadeIds());
  MatrixXfCol same = MatrixXfCol::Ones(4, 3);
  std::vector<std::int32_t> one = {0, 0, 0, 0};
  EXPECT_FALSE(splitCluster(same, one, 0, 1, 1));
  EXPECT_EQ(one, (std::vector<std::int32_t>{0, 0, 0, 0}));
  std::vector<std::int32_t> wrong = {0, 0};
  EXPECT_THROW(splitCluster(s, wrong, 0, 1, 1), Error);
}

TEST(ClusterEdit, MergeThenCompactRenumbersInOrder) {
  std::vector<std::int32_t> ids = handMadeIds();
  mergeClusters(ids, 0, 2);
  EXPECT_EQ(clusterSizes(ids, 3), (std::vector<int>{0, 4, 6}));
  std::vector<int> oldOf = compactClusters(ids, 3);
  EXPECT_EQ(oldOf, (std::vector<int>{1, 2}));
  EXPECT_EQ(ids, (std::vector<std::int32_t>{1, 1, 1, 1, 1, 0, 0, 0, 0, 1}));
  // Nothing empty: unchanged.
  std::vector<std::int32_t> full = handMadeIds();
  EXPECT_EQ(compactClusters(full, 3), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(full, handMadeIds());
  EXPECT_THROW(clusterSizes(full, 2), Error);
}

}  // namespace
}  // namespace nbtf
