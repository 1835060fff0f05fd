// SPDX-License-Identifier: GPL-2.0-or-later
// A peer for splatbench's k-NN leaf radii: nanoflann (Debian's libnanoflann-dev), the exact k
// nearest of every point of a LAS 1.2 file, in f32 coordinates relative to the smallest
// corner, queries over OpenMP threads in the tree's leaf order (spatially coherent: its best
// case; in file order its queries took 4x longer). The tree build is nanoflann's own, one
// thread (1.4.3 has no parallel build). Prints the phases' seconds and the median k-th
// distance, which the SciPy peer prints too. Built and run by scripts/knn-peers.sh.
#include <nanoflann.hpp>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

struct Cloud {
  std::vector<float> p;  // x, y, z of each point
  size_t kdtree_get_point_count() const { return p.size() / 3; }
  float kdtree_get_pt(size_t i, size_t d) const { return p[3 * i + d]; }
  template <class B>
  bool kdtree_get_bbox(B&) const { return false; }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>,
                                                 Cloud, 3, uint32_t>;

static double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s LAS K\n", argv[0]);
    return 2;
  }
  const int k = std::atoi(argv[2]);
  double t0 = now();
  std::ifstream f(argv[1], std::ios::binary);
  std::vector<char> raw((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (raw.size() < 227) {
    std::fprintf(stderr, "%s: not a LAS 1.2 file\n", argv[1]);
    return 1;
  }
  uint32_t off, n;
  uint16_t rec;
  double scale[3];
  std::memcpy(&off, &raw[96], 4);
  std::memcpy(&rec, &raw[105], 2);
  std::memcpy(&n, &raw[107], 4);
  std::memcpy(scale, &raw[131], 24);
  if (raw.size() < off + size_t(n) * rec || n <= uint32_t(k)) {
    std::fprintf(stderr, "%s: short file or too few points\n", argv[1]);
    return 1;
  }
  auto coord = [&](size_t i, int a) {
    int32_t v;
    std::memcpy(&v, &raw[off + i * rec + 4 * a], 4);
    return v;
  };
  int32_t lo[3] = {INT32_MAX, INT32_MAX, INT32_MAX};
  for (size_t i = 0; i < n; i++)
    for (int a = 0; a < 3; a++) lo[a] = std::min(lo[a], coord(i, a));
  Cloud c;
  c.p.resize(size_t(n) * 3);
  for (size_t i = 0; i < n; i++)
    for (int a = 0; a < 3; a++) c.p[3 * i + a] = float(double(coord(i, a) - lo[a]) * scale[a]);
  double t1 = now();
  Tree tree(3, c, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  double t2 = now();
  std::vector<float> kth(n);
#pragma omp parallel
  {
    // k + 1: the point itself is its own nearest.
    std::vector<uint32_t> idx(k + 1);
    std::vector<float> d(k + 1);
#pragma omp for schedule(dynamic, 4096)
    for (size_t j = 0; j < n; j++) {
      size_t i = tree.vAcc[j];
      tree.knnSearch(&c.p[3 * i], k + 1, idx.data(), d.data());
      kth[i] = std::sqrt(d[k]);
    }
  }
  double t3 = now();
  std::nth_element(kth.begin(), kth.begin() + n / 2, kth.end());
  std::printf("nanoflann n=%u read %.2f s build %.2f s query %.2f s knn %.2f s median_kth %.5f\n", n,
              t1 - t0, t2 - t1, t3 - t2, t3 - t1, kth[n / 2]);
  return 0;
}
