// loops SCANS_DIR PRESET [--no-verify] [--map MAP.soliddb] [--odometry FILE]: runs solid's loop
// detector over a folder of PCD keyframes and prints the loops as CSV, the same header and rows as
// `solid detect`'s loops.csv. With --map, the keyframes are a new session against a saved map
// (`solid map build`): its loops into the map are held until consistent loops place the session
// there, then released, and the placement is printed to stderr. With --odometry, the detector's
// own odometry (its poses of the keyframes, given none) is written to FILE as `solid detect`'s
// odometry.csv.
//
// It is laid out as a SLAM system uses the detector:
//   odometry thread    reads each keyframe (here: the next PCD file) and prepares it
//                      (solid_detector_prepare: describe + registration cloud, the heavy part),
//                      then queues it;
//   loop thread        adds the keyframes in order (solid_detector_add_scan) and hands each loop,
//                      and the loops a placement in the map released, to the back-end;
//   back-end (main)    turns each loop into a pose-graph factor: T_query_candidate and its 6x6
//                      information (here: prints the rows, in query order as loops.csv is).
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

// The own odometry's name of a pose source, as odometry.csv writes it.
static const char* source_name(SolidPoseSource s) {
  switch (s) {
    case SOLID_POSE_SOURCE_GIVEN: return "given";
    case SOLID_POSE_SOURCE_CHAINED: return "chained";
    case SOLID_POSE_SOURCE_STARTED: return "started";
    default: return "";
  }
}

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  bool verify = true;
  std::string map_path, odometry_path;
  bool usage = args.size() < 2;
  for (size_t i = 2; i < args.size() && !usage; i++) {
    if (args[i] == "--no-verify") {
      verify = false;
    } else if ((args[i] == "--map" || args[i] == "--odometry") && i + 1 < args.size()) {
      (args[i] == "--map" ? map_path : odometry_path) = args[i + 1];
      i++;
    } else {
      usage = true;
    }
  }
  if (usage) {
    std::fprintf(stderr, "usage: loops SCANS_DIR PRESET [--no-verify] [--map MAP.soliddb] [--odometry FILE]\n");
    return 2;
  }
  const std::string preset = args[1];
  SolidConfig* config = nullptr;
  SolidDetectorConfig* detector_config = nullptr;
  SolidDetector* detector = nullptr;
  int rc = 0;
  try {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(args[0])) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
      if (e.is_regular_file() && ext == ".pcd") files.push_back(e.path());
    }
    if (files.empty()) throw std::runtime_error(args[0] + ": no .pcd files");
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
    if (map_path.empty()) {
      check(solid_detector_new(config, detector_config, &detector), "detector");
    } else {
      // A saved map: the detector shares its places (no copy) and its scans form a new session.
      SolidDatabase* map = nullptr;
      check(solid_database_load(map_path.c_str(), &map), map_path);
      SolidStatus s = solid_detector_from_database(map, detector_config, &detector);
      solid_database_free(map);
      check(s, "detector");
    }
    uint32_t session = 0;
    size_t first_id = 0;
    check(solid_detector_session(detector, &session, &first_id), "session");

    Channel<Keyframe> keyframes;
    Channel<SolidLoop> loops;
    std::string odometry_error, loop_error;
    std::string own_odometry = "frame,source,chain_frame,pose\n";  // odometry.csv's rows

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
      int chain_frame = -1;
      while (auto kf = keyframes.pop()) {
        if (!loop_error.empty()) {
          solid_scan_free(kf->scan);
          continue;
        }
        SolidLoop lp;
        bool found = false;
        SolidStep step;
        SolidStatus s = solid_detector_add_scan(detector, kf->scan, kf->timestamp, nullptr, &lp, &found);
        if (s == SOLID_STATUS_OK) s = solid_detector_last_step(detector, &step);
        if (s != SOLID_STATUS_OK) {
          loop_error = std::string("add: ") + solid_last_error();
          continue;
        }
        if (found) loops.push(lp);
        // Loops into the map of earlier keyframes, held until this step placed the session.
        if (step.released > 0) {
          std::vector<SolidLoop> released(step.released);
          size_t n = 0;
          if (solid_detector_released(detector, released.data(), released.size(), &n) != SOLID_STATUS_OK) {
            loop_error = std::string("released: ") + solid_last_error();
            continue;
          }
          for (size_t k = 0; k < n; k++) loops.push(released[k]);
        }
        if (step.placement != SOLID_PLACEMENT_NONE) {
          std::fprintf(stderr, "%s in the map at keyframe %u, released %zu loops\n",
                       step.placement == SOLID_PLACEMENT_PLACED ? "placed" : "revised",
                       step.query, step.released);
        }
        // The pose the step's checks used: without the caller's, the detector's own odometry.
        if (step.pose_source == SOLID_POSE_SOURCE_STARTED) chain_frame++;
        if (step.pose_source == SOLID_POSE_SOURCE_CHAINED || step.pose_source == SOLID_POSE_SOURCE_STARTED) {
          char row[512];
          int w = std::snprintf(row, sizeof row, "%lld,%s,%d,", frame_of[step.query - first_id],
                                source_name(step.pose_source), chain_frame);
          for (int k = 0; k < 12; k++)
            w += std::snprintf(row + w, sizeof row - w, k ? " %.9g" : "%.9g", step.pose[k]);
          own_odometry += std::string(row) + "\n";
        }
      }
      loops.close();
    });

    // Back-end: each loop is a relative-pose factor between two keyframes. A released loop
    // belongs to an earlier keyframe: the rows are printed in query order at the end.
    std::vector<std::pair<uint32_t, std::string>> rows;
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
      char row[1024];
      int w = std::snprintf(row, sizeof row, "%u,%u,%.6f,%.6f,%.3f,%s,%s,%u,%u,%s,%s,", lp->query, lp->candidate,
                            lp->distance, lp->score, lp->heading_deg, fmt(times[0], "%.6f").c_str(),
                            fmt(times[1], "%.6f").c_str(), sessions[0], sessions[1], frames[0].c_str(),
                            frames[1].c_str());
      if (lp->verified) {
        // lp->pose (T_query_candidate) and lp->information are the factor a pose graph adds.
        double q[4];
        quaternion(lp->pose, q);
        std::snprintf(row + w, sizeof row - w, "True,%.6f,%.6f,%.6f,%.9f,%.9f,%.9f,%.9f,%s,%s\n", lp->pose[3],
                      lp->pose[7], lp->pose[11], q[0], q[1], q[2], q[3], fmt(lp->fitness, "%.4f").c_str(),
                      fmt(lp->rmse, "%.4f").c_str());
      } else {
        std::snprintf(row + w, sizeof row - w, "False,,,,,,,,,\n");
      }
      rows.emplace_back(lp->query, row);
    }
    odometry.join();
    closure.join();
    if (!odometry_error.empty()) throw std::runtime_error(odometry_error);
    if (!loop_error.empty()) throw std::runtime_error(loop_error);
    if (!backend_error.empty()) throw std::runtime_error(backend_error);
    std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::printf(
        "query,candidate,distance,score,heading_deg,query_time,candidate_time,query_session,"
        "candidate_session,query_frame,candidate_frame,verified,x,y,z,qx,qy,qz,qw,fitness,rmse\n");
    for (const auto& r : rows) std::fputs(r.second.c_str(), stdout);
    if (!odometry_path.empty()) {
      FILE* f = std::fopen(odometry_path.c_str(), "w");
      bool written = f != nullptr && std::fputs(own_odometry.c_str(), f) >= 0;
      if (f != nullptr && std::fclose(f) != 0) written = false;
      if (!written) throw std::runtime_error(odometry_path + ": cannot write");
    }
    if (!map_path.empty()) {
      // Where the session lies in the map (T_map_world: the session's frame into the map's).
      SolidMapAnchor anchor;
      bool placed = false;
      check(solid_detector_map_anchor(detector, &anchor, &placed), "map anchor");
      if (placed)
        std::fprintf(stderr, "anchor: %zu loops over %.3f m, keyframes %u..%u, translation %.6f %.6f %.6f\n",
                     anchor.loops, anchor.metres, anchor.first_query, anchor.last_query, anchor.transform[3],
                     anchor.transform[7], anchor.transform[11]);
      else
        std::fprintf(stderr, "anchor: not placed\n");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "loops: %s\n", e.what());
    rc = 1;
  }
  solid_detector_free(detector);
  solid_detector_config_free(detector_config);
  solid_config_free(config);
  return rc;
}
