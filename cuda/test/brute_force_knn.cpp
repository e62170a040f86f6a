#include "brute_force_knn.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

namespace gf_test {

namespace {

inline float sqDist(const float* a, const float* b) {
  const float dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return (dx * dx + dy * dy) + dz * dz;
}

}  // namespace

void bruteForceRow(const float* xyz, std::size_t n, std::size_t q, int k, std::int32_t* idx,
                   float* d2) {
  // Max-heap of the k best (distance, index) pairs.
  std::vector<std::pair<float, std::int32_t>> heap;
  heap.reserve(static_cast<std::size_t>(k) + 1);
  for (std::size_t j = 0; j < n; ++j) {
    const std::pair<float, std::int32_t> c(sqDist(xyz + 3 * q, xyz + 3 * j),
                                           static_cast<std::int32_t>(j));
    if (heap.size() < static_cast<std::size_t>(k)) {
      heap.push_back(c);
      std::push_heap(heap.begin(), heap.end());
    } else if (c < heap.front()) {
      std::pop_heap(heap.begin(), heap.end());
      heap.back() = c;
      std::push_heap(heap.begin(), heap.end());
    }
  }
  std::sort_heap(heap.begin(), heap.end());
  for (int j = 0; j < k; ++j) {
    if (static_cast<std::size_t>(j) < heap.size()) {
      idx[j] = heap[j].second;
      d2[j] = heap[j].first;
    } else {
      idx[j] = -1;
      d2[j] = std::numeric_limits<float>::infinity();
    }
  }
}

std::string compareRow(const float* xyz, std::size_t n, std::size_t q, int k,
                       const std::int32_t* idx, const float* d2) {
  std::vector<std::int32_t> ri(k);
  std::vector<float> rd(k);
  bruteForceRow(xyz, n, q, k, ri.data(), rd.data());
  const std::int32_t* gi = idx + q * static_cast<std::size_t>(k);
  const float* gd = d2 ? d2 + q * static_cast<std::size_t>(k) : nullptr;
  for (int j = 0; j < k; ++j) {
    if (gi[j] != ri[j] || (gd && !(gd[j] == rd[j]))) {
      std::ostringstream os;
      os << "row " << q << " slot " << j << ": got (" << gi[j] << ", " << (gd ? gd[j] : -1.f)
         << "), brute force (" << ri[j] << ", " << rd[j] << ")";
      return os.str();
    }
  }
  return std::string();
}

std::size_t compareRows(const float* xyz, std::size_t n, int k, const std::int32_t* idx,
                        const float* d2, const std::vector<std::size_t>& queries,
                        std::string* first) {
  const std::size_t m = queries.empty() ? n : queries.size();
  std::size_t bad = 0;
  std::string first_msg;
#pragma omp parallel for schedule(dynamic, 16) reduction(+ : bad)
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(m); ++t) {
    const std::size_t q = queries.empty() ? static_cast<std::size_t>(t) : queries[t];
    const std::string msg = compareRow(xyz, n, q, k, idx, d2);
    if (!msg.empty()) {
      ++bad;
#pragma omp critical
      if (first_msg.empty()) first_msg = msg;
    }
  }
  if (first) *first = first_msg;
  return bad;
}

std::vector<float> readKittiBin(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::vector<float> rec;
  if (!f) return rec;
  f.seekg(0, std::ios::end);
  const std::size_t bytes = static_cast<std::size_t>(f.tellg());
  f.seekg(0);
  rec.resize(bytes / sizeof(float));
  f.read(reinterpret_cast<char*>(rec.data()), static_cast<std::streamsize>(rec.size() * 4));
  std::vector<float> xyz;
  xyz.reserve(rec.size() / 4 * 3);
  for (std::size_t i = 0; i + 3 < rec.size(); i += 4) {
    xyz.push_back(rec[i]);
    xyz.push_back(rec[i + 1]);
    xyz.push_back(rec[i + 2]);
  }
  return xyz;
}

}  // namespace gf_test
