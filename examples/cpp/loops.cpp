// loops SCANS_DIR PRESET [--no-verify]: runs solid's loop detector over a folder of PCD keyframes
// and prints the loops as CSV, the same header and rows as `solid detect`'s loops.csv.
//
// It is laid out as a SLAM system uses the detector:
//   odometry thread    reads each keyframe (here: the next PCD file) and prepares it
//                      (solid_detector_prepare: describe + registration cloud, the heavy part),
//                      then queues it;
//   loop thread        adds the keyframes in order (solid_detector_add_scan) and hands each loop
//                      to the back-end;
//   back-end (main)    turns each loop into a pose-graph factor: T_query_candidate and its 6x6
//                      information (here: prints the row).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <solid.h>

#include "../c/scan_file.h"

namespace fs = std::filesystem;

// A queue between two threads; close() ends the consumer's loop.
template <typename T>
class Channel {
 public:
  void push(T v) {
    {
      std::lock_guard<std::mutex> lock(m_);
      q_.push_back(std::move(v));
    }
    cv_.notify_one();
  }
  void close() {
    {
      std::lock_guard<std::mutex> lock(m_);
      closed_ = true;
    }
    cv_.notify_all();
  }
  // The next value, or nothing once the queue is closed and empty.
  std::optional<T> pop() {
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait(lock, [&] { return closed_ || !q_.empty(); });
    if (q_.empty()) return std::nullopt;
    T v = std::move(q_.front());
    q_.pop_front();
    return v;
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<T> q_;
  bool closed_ = false;
};

// Throws solid's message for a failed call.
static void check(SolidStatus s, const std::string& what) {
  if (s != SOLID_STATUS_OK) throw std::runtime_error(what + ": " + solid_last_error());
}

// The order `solid` sorts a folder in: runs of digits by value ("2.pcd" before "10.pcd").
static bool natural_less(const std::string& a, const std::string& b) {
  auto tokens = [](const std::string& s) {
    std::vector<std::pair<int, std::string>> out;
    for (size_t i = 0; i < s.size();) {
      size_t j = i;
      bool digit = std::isdigit(static_cast<unsigned char>(s[i])) != 0;
      while (j < s.size() && (std::isdigit(static_cast<unsigned char>(s[j])) != 0) == digit) j++;
      std::string t = s.substr(i, j - i);
      if (digit) {
        t.erase(0, std::min(t.find_first_not_of('0'), t.size() - 1));  // compare by value
        out.emplace_back(0, std::string(20 - std::min<size_t>(t.size(), 20), '0') + t);
      } else {
        std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
        out.emplace_back(1, t);
      }
      i = j;
    }
    return out;
  };
  return tokens(a) < tokens(b);
}

// (qx, qy, qz, qw) of the rotation of a row-major 4x4 pose, qw >= 0 (Shepperd's method, as the
// Python package computes it, operation for operation).
static void quaternion(const double* P, double q[4]) {
  auto m = [&](int i, int j) { return P[4 * i + j]; };
  double tr = m(0, 0) + m(1, 1) + m(2, 2), s;
  if (tr > 0) {
    s = 2.0 * std::sqrt(1.0 + tr);
    q[0] = (m(2, 1) - m(1, 2)) / s, q[1] = (m(0, 2) - m(2, 0)) / s, q[2] = (m(1, 0) - m(0, 1)) / s, q[3] = 0.25 * s;
  } else if (m(0, 0) > m(1, 1) && m(0, 0) > m(2, 2)) {
    s = 2.0 * std::sqrt(1.0 + m(0, 0) - m(1, 1) - m(2, 2));
    q[0] = 0.25 * s, q[1] = (m(0, 1) + m(1, 0)) / s, q[2] = (m(0, 2) + m(2, 0)) / s, q[3] = (m(2, 1) - m(1, 2)) / s;
  } else if (m(1, 1) > m(2, 2)) {
    s = 2.0 * std::sqrt(1.0 + m(1, 1) - m(0, 0) - m(2, 2));
    q[0] = (m(0, 1) + m(1, 0)) / s, q[1] = 0.25 * s, q[2] = (m(1, 2) + m(2, 1)) / s, q[3] = (m(0, 2) - m(2, 0)) / s;
  } else {
    s = 2.0 * std::sqrt(1.0 + m(2, 2) - m(0, 0) - m(1, 1));
    q[0] = (m(0, 2) + m(2, 0)) / s, q[1] = (m(1, 2) + m(2, 1)) / s, q[2] = 0.25 * s, q[3] = (m(1, 0) - m(0, 1)) / s;
  }
  double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  double sign = q[3] < 0 ? -1.0 : 1.0;
  for (int i = 0; i < 4; i++) q[i] = sign * q[i] / n;
}

// A number as loops.csv writes it: empty when unknown (NaN).
static std::string fmt(double v, const char* format) {
  if (std::isnan(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

struct Keyframe {
  SolidScan* scan;  // owned until handed to solid_detector_add_scan
  double timestamp;
};

int main(int argc, char** argv) {
  if (argc < 3 || argc > 4 || (argc == 4 && std::string(argv[3]) != "--no-verify")) {
    std::fprintf(stderr, "usage: loops SCANS_DIR PRESET [--no-verify]\n");
    return 2;
  }
  const std::string preset = argv[2];
  const bool verify = argc < 4;
  SolidConfig* config = nullptr;
  SolidDetectorConfig* detector_config = nullptr;
  SolidDetector* detector = nullptr;
  int rc = 0;
  try {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(argv[1])) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      if (e.is_regular_file() && ext == ".pcd") files.push_back(e.path());
    }
    if (files.empty()) throw std::runtime_error(std::string(argv[1]) + ": no .pcd files");
    std::sort(files.begin(), files.end(),
              [](const fs::path& a, const fs::path& b) { return natural_less(a.filename().string(), b.filename().string()); });
    // Frame numbers from the file names when they all are numbers, else the index.
    std::vector<long long> frame_of(files.size());
    bool numbered = true;
    for (size_t i = 0; i < files.size(); i++) {
      std::string stem = files[i].stem().string();
      numbered = numbered && !stem.empty() && stem.size() < 19 &&
                 std::all_of(stem.begin(), stem.end(), [](unsigned char c) { return std::isdigit(c); });
      frame_of[i] = numbered ? std::stoll(stem) : 0;
    }
    for (size_t i = 0; !numbered && i < files.size(); i++) frame_of[i] = static_cast<long long>(i);

    check(solid_config_new(preset.c_str(), &config), "preset");
    check(solid_detector_config_new(preset.c_str(), &detector_config), "preset");
    check(solid_detector_config_set(detector_config, "verify", verify ? 1.0 : 0.0), "verify");
    check(solid_detector_new(config, detector_config, &detector), "detector");
    uint32_t session = 0;
    size_t first_id = 0;
    check(solid_detector_session(detector, &session, &first_id), "session");

    Channel<Keyframe> keyframes;
    Channel<SolidLoop> loops;
    std::string odometry_error, loop_error;

    // Odometry: the keyframes in order, prepared on this thread while the detector works.
    std::thread odometry([&] {
      try {
        for (const auto& f : files) {
          ScanFile cloud;
          char err[512];
          if (scan_file_read(f.string().c_str(), &cloud, err, sizeof err) != 0) throw std::runtime_error(err);
          SolidScan* scan = nullptr;
          SolidStatus s = solid_detector_prepare(detector, &cloud.points, &scan);
          scan_file_free(&cloud);  // the prepared scan keeps nothing of the points
          check(s, f.string());
          keyframes.push(Keyframe{scan, NAN});  // a SLAM system passes the keyframe's time and pose
        }
      } catch (const std::exception& e) {
        odometry_error = e.what();
      }
      keyframes.close();
    });

    // Loop closure: one step per keyframe, in order; loops go to the back-end.
    std::thread closure([&] {
      while (auto kf = keyframes.pop()) {
        if (!loop_error.empty()) {
          solid_scan_free(kf->scan);
          continue;
        }
        SolidLoop lp;
        bool found = false;
        SolidStatus s = solid_detector_add_scan(detector, kf->scan, kf->timestamp, nullptr, &lp, &found);
        if (s != SOLID_STATUS_OK) {
          loop_error = std::string("add: ") + solid_last_error();
        } else if (found) {
          loops.push(lp);
        }
      }
      loops.close();
    });

    // Back-end: each loop is a relative-pose factor between two keyframes.
    std::printf(
        "query,candidate,distance,score,heading_deg,query_time,candidate_time,query_session,"
        "candidate_session,query_frame,candidate_frame,verified,x,y,z,qx,qy,qz,qw,fitness,rmse\n");
    std::string backend_error;
    while (auto lp = loops.pop()) {
      if (!backend_error.empty()) continue;  // drain, so that the other threads finish
      uint32_t sessions[2];
      double times[2];
      uint32_t ids[2] = {lp->query, lp->candidate};
      std::string frames[2];
      bool ok = true;
      for (int k = 0; k < 2 && ok; k++) {
        ok = solid_detector_entry(detector, ids[k], &sessions[k], &times[k], nullptr) == SOLID_STATUS_OK;
        if (ids[k] >= first_id && ids[k] - first_id < frame_of.size())
          frames[k] = std::to_string(frame_of[ids[k] - first_id]);
      }
      if (!ok) {
        backend_error = std::string("entry: ") + solid_last_error();
        continue;
      }
      std::printf("%u,%u,%.6f,%.6f,%.3f,%s,%s,%u,%u,%s,%s,", lp->query, lp->candidate, lp->distance, lp->score,
                  lp->heading_deg, fmt(times[0], "%.6f").c_str(), fmt(times[1], "%.6f").c_str(), sessions[0],
                  sessions[1], frames[0].c_str(), frames[1].c_str());
      if (lp->verified) {
        // lp->pose (T_query_candidate) and lp->information are the factor a pose graph adds.
        double q[4];
        quaternion(lp->pose, q);
        std::printf("True,%.6f,%.6f,%.6f,%.9f,%.9f,%.9f,%.9f,%s,%s\n", lp->pose[3], lp->pose[7], lp->pose[11], q[0],
                    q[1], q[2], q[3], fmt(lp->fitness, "%.4f").c_str(), fmt(lp->rmse, "%.4f").c_str());
      } else {
        std::printf("False,,,,,,,,,\n");
      }
    }
    odometry.join();
    closure.join();
    if (!odometry_error.empty()) throw std::runtime_error(odometry_error);
    if (!loop_error.empty()) throw std::runtime_error(loop_error);
    if (!backend_error.empty()) throw std::runtime_error(backend_error);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "loops: %s\n", e.what());
    rc = 1;
  }
  solid_detector_free(detector);
  solid_detector_config_free(detector_config);
  solid_config_free(config);
  return rc;
}
