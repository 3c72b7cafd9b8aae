// Scenes from simulation files: GSD (files written by python3-gsd, at test
// time when it is installed, and two committed ones from
// tests/data/write_gsd_scenes.py), LAMMPS data and dump files (committed,
// written by Debian's lmp from tests/data/lammps_triclinic.in).
// What is read is checked against what the writer was given; the pairs
// against a brute force over every periodic image; malformed files against
// their messages.
#include <sys/stat.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "pwcontact/pwcontact.hpp"

namespace {

namespace fs = std::filesystem;
using pwcontact::Box;
using pwcontact::Scene;

const fs::path data_dir = PWCONTACT_TEST_DATA;

// Every pair (i < j) with mu < cutoff at some image n1 a1 + n2 a2 + n3 a3
// (|n| <= 2) of the centres as given, by the reference path.
std::set<std::pair<std::uint32_t, std::uint32_t>> brute_force(const pwcontact::ParticleStore& s,
                                                              const Box& box, double cutoff) {
  const double lx = box.length[0], ly = box.length[1], lz = box.length[2];
  const double a[3][3] = {
      {lx, 0, 0}, {box.tilt[0] * ly, ly, 0}, {box.tilt[1] * lz, box.tilt[2] * lz, lz}};
  const int reach_z = box.two_dimensional ? 0 : 2, reach = box.periodic ? 2 : 0;
  std::set<std::pair<std::uint32_t, std::uint32_t>> found;
  for (std::uint32_t i = 0; i < s.size(); ++i)
    for (std::uint32_t j = i + 1; j < s.size(); ++j) {
      double qi[6], qj[6];
      for (int k = 0; k < 6; ++k) qi[k] = s.q(k)[i], qj[k] = s.q(k)[j];
      bool near = false;
      for (int n1 = -reach; n1 <= reach && !near; ++n1)
        for (int n2 = -reach; n2 <= reach && !near; ++n2)
          for (int n3 = -std::min(reach, reach_z); n3 <= std::min(reach, reach_z) && !near; ++n3) {
            double r[3];
            for (int k = 0; k < 3; ++k)
              r[k] = s.centre(k)[j] - s.centre(k)[i] + n1 * a[0][k] + n2 * a[1][k] + n3 * a[2][k];
            const auto result = pwcontact::contact_function<double>(r, qi, qj);
            near = result.status == pwcontact::Status::ok && result.mu2 < cutoff * cutoff;
          }
      if (near) found.insert({i, j});
    }
  return found;
}

void expect_screen_matches_brute_force(const Scene& scene, double cutoff, const std::string& what) {
  pwcontact::ScreenedPairs pairs;
  pwcontact::ScreenOptions options;
  options.cutoff = cutoff;
  pwcontact::screen_pairs(scene.particles, scene.box, options, pairs);
  std::set<std::pair<std::uint32_t, std::uint32_t>> got;
  for (std::size_t k = 0; k < pairs.size(); ++k) got.insert({pairs.i[k], pairs.j[k]});
  const auto expected = brute_force(scene.particles, scene.box, cutoff);
  EXPECT_EQ(got, expected) << what;
  EXPECT_GT(expected.size(), 0u) << what << ": the scene should have pairs";
  std::printf("[ measured ] %s: %zu pairs, the brute force's\n", what.c_str(), got.size());
}

// The bounding radius the store gives semi-axes a (rounded outwards).
void expect_radii(const Scene& scene, std::size_t i, double largest, double smallest,
                  const std::string& what) {
  EXPECT_NEAR(scene.particles.bounding_radius()[i], largest, 1e-12 * largest)
      << what << ", particle " << i;
  EXPECT_NEAR(scene.particles.inscribed_radius()[i], smallest, 1e-12 * smallest)
      << what << ", particle " << i;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument)";
}

// ---------------------------------------------------------------------------
// GSD

TEST(SceneFiles, ACommittedGsdFileOfTwoTypesInATriclinicBox) {
  const Scene scene = pwcontact::read_gsd((data_dir / "hoomd_triclinic.gsd").string());
  EXPECT_EQ(scene.particles.size(), 60u);
  EXPECT_EQ(scene.frames, 1u);
  EXPECT_EQ(scene.box.length, (std::array<double, 3>{6, 6, 5}));
  EXPECT_NEAR(scene.box.tilt[0], 0.3, 1e-7);  // (float32 in the file)
  EXPECT_NEAR(scene.box.tilt[1], -0.2, 1e-7);
  EXPECT_NEAR(scene.box.tilt[2], 0.1, 1e-7);
  ASSERT_EQ(scene.type_names, (std::vector<std::string>{"A", "B"}));
  // The file's types are the store's shape types (radii once per type).
  ASSERT_EQ(scene.particles.types(), 2u);
  EXPECT_EQ(scene.particles.type_semi_axes(0), (std::array<double, 3>{0.6, 0.35, 0.25}));
  EXPECT_EQ(scene.particles.type_semi_axes(1), (std::array<double, 3>{0.35, 0.35, 0.35}));
  EXPECT_EQ(scene.particles.type_id(), scene.type_id);
  for (std::size_t i = 0; i < scene.particles.size(); ++i) {
    if (scene.type_id[i] == 0)
      expect_radii(scene, i, 0.6, 0.25, "Ellipsoid a 0.6 b 0.35 c 0.25");
    else
      expect_radii(scene, i, 0.35, 0.35, "Sphere diameter 0.7");
  }
  expect_screen_matches_brute_force(scene, 1.2, "committed GSD, triclinic");
}

TEST(SceneFiles, ACommittedGsdFileOfEllipsesInTwoDimensions) {
  const Scene scene = pwcontact::read_gsd((data_dir / "hoomd_ellipses_2d.gsd").string());
  EXPECT_TRUE(scene.box.two_dimensional);
  EXPECT_NEAR(scene.box.tilt[0], 0.25, 1e-7);
  for (std::size_t i = 0; i < scene.particles.size(); ++i) {
    EXPECT_EQ(scene.particles.centre(2)[i], 0);
    expect_radii(scene, i, 0.6, 0.3, "Ellipse a 0.6 b 0.3");
  }
  expect_screen_matches_brute_force(scene, 1.2, "committed GSD, 2D");
}

// Runs a python3-gsd script in `directory`; false when python3-gsd is not
// installed (the tests that need it are then skipped).
bool run_python_gsd(const fs::path& directory, const std::string& script) {
  if (std::system("/usr/bin/python3 -c 'import gsd.hoomd, numpy' 2>/dev/null") != 0) return false;
  const fs::path file = directory / "write.py";
  std::ofstream(file) << script;
  const std::string command = "cd '" + directory.string() + "' && /usr/bin/python3 write.py";
  return std::system(command.c_str()) == 0;
}

class GsdWritten : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::path(::testing::TempDir()) / "pwcontact_gsd.XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    directory_ = pattern;
  }
  void TearDown() override { fs::remove_all(directory_); }
  fs::path directory_;
};

// Frames of 300 particles, three types (two ellipsoids and a sphere), the
// second frame with only the positions (the rest from frame 0 by the
// schema), both ways of the gsd API (Snapshot in 2.7, Frame later).
const char* three_frames = R"(
import gsd.hoomd, numpy as np
Frame = getattr(gsd.hoomd, 'Frame', None) or gsd.hoomd.Snapshot
rng = np.random.default_rng(11)
N = 300
f = Frame()
f.particles.N = N
f.particles.types = ['needle', 'disc', 'ball']
f.particles.typeid = rng.integers(0, 3, N).astype(np.uint32)
f.particles.position = rng.uniform(-4, 4, (N, 3)).astype(np.float32)
q = rng.normal(size=(N, 4)); q /= np.linalg.norm(q, axis=1)[:, None]
f.particles.orientation = q.astype(np.float32)
f.particles.type_shapes = [{'type': 'Ellipsoid', 'a': 0.9, 'b': 0.2, 'c': 0.2},
                           {'type': 'Ellipsoid', 'a': 0.6, 'b': 0.6, 'c': 0.15},
                           {'type': 'Sphere', 'diameter': 0.8}]
f.configuration.box = [9, 9, 9, 0.4, 0.0, -0.3]
np.savetxt('frame0.txt', np.hstack([f.particles.position, f.particles.orientation, f.particles.typeid[:, None]]))
with gsd.hoomd.open('scene.gsd', 'wb') as out:
    out.append(f)
    g = Frame()
    g.particles.N = N
    g.particles.position = (f.particles.position * 0.97).astype(np.float32)
    g.configuration.box = f.configuration.box
    out.append(g)
    out.append(g)
)";

TEST_F(GsdWritten, FramesWrittenByPythonGsdAreReadWithTheSchemasDefaults) {
  if (!run_python_gsd(directory_, three_frames)) GTEST_SKIP() << "python3-gsd is not installed";
  const std::string path = (directory_ / "scene.gsd").string();
  const Scene first = pwcontact::read_gsd(path, 0);
  const Scene last = pwcontact::read_gsd(path);
  EXPECT_EQ(first.frames, 3u);
  EXPECT_EQ(last.frame, 2u);
  // Frame 0 against the numbers the writer was given.
  std::ifstream table(directory_ / "frame0.txt");
  const double axes[3][3] = {{0.9, 0.2, 0.2}, {0.6, 0.6, 0.15}, {0.4, 0.4, 0.4}};
  for (std::size_t i = 0; i < 300; ++i) {
    double v[8];
    for (double& x : v) table >> x;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(first.particles.centre(k)[i], double(float(v[k]))) << i;
    EXPECT_EQ(first.type_id[i], std::uint32_t(v[7])) << i;
    const auto q = pwcontact::quadratic_form_from_quaternion(
        {axes[first.type_id[i]][0], axes[first.type_id[i]][1], axes[first.type_id[i]][2]},
        {double(float(v[3])), double(float(v[4])), double(float(v[5])), double(float(v[6]))});
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(first.particles.q(k)[i], q[k], 1e-12) << i;
    // The last frame: moved centres, frame 0's types and orientations.
    EXPECT_EQ(last.type_id[i], first.type_id[i]);
    for (int k = 0; k < 6; ++k) EXPECT_EQ(last.particles.q(k)[i], first.particles.q(k)[i]);
    EXPECT_EQ(last.particles.centre(0)[i], double(float(float(v[0]) * 0.97f)));
  }
  expect_screen_matches_brute_force(last, 1, "python3-gsd, last frame");
}

TEST_F(GsdWritten, FilesOfTheWriterAreReadByPythonGsd) {
  // Two frames written here, read back by python3-gsd (an independent
  // reader of the format), which prints what it finds.
  {
    std::ofstream out(directory_ / "written.gsd", std::ios::binary);
    pwcontact::GsdWriter writer(out);
    writer.write("configuration/box", std::vector<float>{5, 6, 7, 0.1f, -0.2f, 0.3f}, 6);
    writer.write("particles/N", std::vector<std::uint32_t>{3}, 1);
    writer.write("particles/types", std::vector<std::string>{"A", "long_name"});
    writer.write("particles/typeid", std::vector<std::uint32_t>{0, 1, 1}, 3);
    writer.write("particles/position", std::vector<float>{0, 0, 0, 1, 2, 3, -1, -2, -2.5f}, 3);
    writer.write("particles/type_shapes",
                 std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})",
                                          R"({"type": "Ellipsoid", "a": 1, "b": 0.5, "c": 0.25})"});
    writer.write("log/particles/overlaps", std::vector<std::uint32_t>{7, 8, 9}, 3);
    writer.end_frame();
    writer.write("particles/N", std::vector<std::uint32_t>{3}, 1);
    writer.write("particles/position", std::vector<double>{0.5, 0, 0, 1, 2, 3, -1, -2, -2.5}, 3);
    writer.end_frame();
    writer.finish();
  }
  // Read by this reader: the second frame takes the rest from frame 0.
  const Scene second = pwcontact::read_gsd((directory_ / "written.gsd").string());
  EXPECT_EQ(second.frames, 2u);
  EXPECT_EQ(second.particles.centre(0)[0], 0.5);
  EXPECT_EQ(second.type_names, (std::vector<std::string>{"A", "long_name"}));
  expect_radii(second, 2, 1, 0.25, "Ellipsoid a 1 b 0.5 c 0.25");
  const char* check = R"(
import gsd.hoomd
with gsd.hoomd.open('written.gsd', 'rb') as t:
    with open('seen.txt', 'w') as out:
        out.write('%d\n' % len(t))
        f = t[0]
        out.write(' '.join('%g' % x for x in f.configuration.box) + '\n')
        out.write(' '.join(f.particles.types) + '\n')
        out.write(' '.join(str(x) for x in f.particles.typeid) + '\n')
        out.write(' '.join('%g' % x for x in f.particles.position.flatten()) + '\n')
        out.write(str(f.particles.type_shapes[1]['c']) + '\n')
        out.write(' '.join(str(x) for x in t.read_frame(0).log['particles/overlaps']) + '\n')
        out.write(' '.join('%g' % x for x in t[1].particles.position[0]) + '\n')
)";
  if (!run_python_gsd(directory_, check)) GTEST_SKIP() << "python3-gsd is not installed";
  std::ifstream seen(directory_ / "seen.txt");
  std::vector<std::string> lines;
  for (std::string line; std::getline(seen, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 8u);
  EXPECT_EQ(lines[0], "2");
  EXPECT_EQ(lines[1], "5 6 7 0.1 -0.2 0.3");
  EXPECT_EQ(lines[2], "A long_name");
  EXPECT_EQ(lines[3], "0 1 1");
  EXPECT_EQ(lines[4], "0 0 0 1 2 3 -1 -2 -2.5");
  EXPECT_EQ(lines[5], "0.25");
  EXPECT_EQ(lines[6], "7 8 9");
  EXPECT_EQ(lines[7], "0.5 0 0");
}

TEST_F(GsdWritten, AFrameIsWrittenBackWithPerParticleValuesForOvito) {
  if (!run_python_gsd(directory_, three_frames)) GTEST_SKIP() << "python3-gsd is not installed";
  const std::string path = (directory_ / "scene.gsd").string();
  // Frame 1 holds only N, the positions and the box: the types, shapes and
  // orientations come from frame 0, and so into the file written.
  std::vector<std::uint32_t> values(300);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = std::uint32_t(i * 7 % 13);
  {
    std::ofstream out(directory_ / "counts.gsd", std::ios::binary);
    pwcontact::write_gsd_frame_with_values(path, 1, "overlaps", values, out);
  }
  const char* check = R"(
import gsd.hoomd, numpy as np
with gsd.hoomd.open('scene.gsd', 'rb') as t:
    source = t[1]
with gsd.hoomd.open('counts.gsd', 'rb') as t:
    f = t[0]
    log = t.read_frame(0).log['particles/overlaps']
    frames = len(t)
ok = (frames == 1 and np.array_equal(f.particles.position, source.particles.position)
      and np.array_equal(f.particles.orientation, source.particles.orientation)
      and np.array_equal(f.particles.typeid, source.particles.typeid)
      and f.particles.types == source.particles.types
      and f.particles.type_shapes == source.particles.type_shapes
      and np.allclose(f.configuration.box, source.configuration.box))
with open('seen.txt', 'w') as out:
    out.write('%s\n' % ok)
    out.write(' '.join(str(x) for x in log) + '\n')
)";
  ASSERT_TRUE(run_python_gsd(directory_, check));
  std::ifstream seen(directory_ / "seen.txt");
  std::string same, logged;
  std::getline(seen, same);
  std::getline(seen, logged);
  EXPECT_EQ(same, "True");
  std::string expected;
  for (std::size_t i = 0; i < values.size(); ++i)
    expected += (i ? " " : "") + std::to_string(values[i]);
  EXPECT_EQ(logged, expected);
  // Values that are not one per particle: refused.
  std::ostringstream out;
  EXPECT_NE(message_of([&] {
              pwcontact::write_gsd_frame_with_values(path, 1, "overlaps", {1, 2}, out);
            }).find("2 values for the 300 particles"),
            std::string::npos);
}

TEST_F(GsdWritten, MalformedGsdFilesAreRefusedWithWhatIsWrong) {
  if (!run_python_gsd(directory_, three_frames)) GTEST_SKIP() << "python3-gsd is not installed";
  const std::string path = (directory_ / "scene.gsd").string();
  // Truncated: the chunks of the later frames beyond the end.
  const auto size = fs::file_size(path);
  fs::copy_file(path, directory_ / "cut.gsd");
  fs::resize_file(directory_ / "cut.gsd", size / 2);
  EXPECT_NE(message_of([&] {
              pwcontact::read_gsd((directory_ / "cut.gsd").string(), 0);
            }).find("truncated"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              pwcontact::read_gsd(path, 3);
            }).find("frame 3 is not in the file (it has 3 frames)"),
            std::string::npos);
  std::ofstream(directory_ / "text.gsd")
      << "this is not a GSD file, but it is long enough to have a header ..."
      << std::string(300, '.');
  EXPECT_NE(message_of([&] {
              pwcontact::read_gsd((directory_ / "text.gsd").string());
            }).find("not a GSD file"),
            std::string::npos);
  // Shapes, types and orientations that cannot be ellipsoids.
  const char* bad = R"(
import gsd.hoomd, numpy as np
Frame = getattr(gsd.hoomd, 'Frame', None) or gsd.hoomd.Snapshot
def write(name, shapes, typeid=(0, 0), orientation=((1, 0, 0, 0), (1, 0, 0, 0)), dimensions=3,
          position=((0, 0, 0), (1, 1, 1))):
    f = Frame()
    f.configuration.dimensions = dimensions
    f.particles.N = 2
    f.particles.types = [chr(65 + k) for k in range(len(shapes))]
    f.particles.typeid = np.array(typeid, dtype=np.uint32)
    f.particles.position = np.array(position, dtype=np.float32)
    f.particles.orientation = np.array(orientation, dtype=np.float32)
    f.particles.type_shapes = shapes
    f.configuration.box = [10, 10, 10 if dimensions == 3 else 0, 0, 0, 0]
    with gsd.hoomd.open(name, 'wb') as out:
        out.append(f)
write('polygon.gsd', [{'type': 'Polygon', 'rounding_radius': 0, 'vertices': [[0, 0], [1, 0], [0, 1]]}])
write('flat.gsd', [{'type': 'Ellipsoid', 'a': 1, 'b': 0, 'c': 1}])
write('typeid.gsd', [{'type': 'Sphere', 'diameter': 1}], typeid=(0, 4))
write('zero_q.gsd', [{'type': 'Ellipsoid', 'a': 1, 'b': 0.5, 'c': 0.5}], orientation=((1, 0, 0, 0), (0, 0, 0, 0)))
ellipse = [{'type': 'Ellipsoid', 'a': 1, 'b': 0.5}]
write('tilted_2d.gsd', ellipse, dimensions=2, position=((0, 0, 0), (1, 1, 0)),
      orientation=((1, 0, 0, 0), (0.8, 0.6, 0, 0)))
write('lifted_2d.gsd', ellipse, dimensions=2, position=((0, 0, 0), (1, 1, 0.5)))
write('nudged_2d.gsd', ellipse, dimensions=2, position=((0, 0, 0), (1, 1, 2.0**-20)))
write('ellipse_2d.gsd', [{'type': 'Ellipse', 'a': 1, 'b': 0.5}], dimensions=2, position=((0, 0, 0), (1, 1, 0)))
write('ellipse_3d.gsd', [{'type': 'Ellipse', 'a': 1, 'b': 0.5}])
)";
  ASSERT_TRUE(run_python_gsd(directory_, bad));
  auto message = [&](const char* file) {
    return message_of([&] { pwcontact::read_gsd((directory_ / file).string()); });
  };
  EXPECT_NE(message("polygon.gsd").find("type 0 ('A'): its shape is 'Polygon', not an ellipsoid"),
            std::string::npos)
      << message("polygon.gsd");
  EXPECT_NE(message("flat.gsd").find("b = 0"), std::string::npos) << message("flat.gsd");
  EXPECT_NE(message("typeid.gsd").find("particle 1 has typeid 4, but there are 1 types"),
            std::string::npos)
      << message("typeid.gsd");
  EXPECT_NE(message("zero_q.gsd").find("frame 0: particle 1"), std::string::npos)
      << message("zero_q.gsd");
  // In two dimensions: rotations about z only, centres in the plane.
  EXPECT_NE(
      message("tilted_2d.gsd").find("particle 1: a two-dimensional scene, but its orientation"),
      std::string::npos)
      << message("tilted_2d.gsd");
  EXPECT_NE(message("lifted_2d.gsd").find("particle 1: a two-dimensional scene, but its z is 0.5"),
            std::string::npos)
      << message("lifted_2d.gsd");
  // A z off the plane by a float32 rounding is shown as it is (it read
  // "0.000001", which looked like a rounding of 0).
  EXPECT_NE(message("nudged_2d.gsd").find("its z is 9.5367431640625e-07, not 0"), std::string::npos)
      << message("nudged_2d.gsd");
  // An Ellipse shape: an ellipse in 2D, refused in 3D.
  const Scene ellipses = pwcontact::read_gsd((directory_ / "ellipse_2d.gsd").string());
  for (std::size_t i = 0; i < 2; ++i) expect_radii(ellipses, i, 1, 0.5, "Ellipse a 1 b 0.5");
  EXPECT_NE(
      message("ellipse_3d.gsd").find("its shape is an Ellipse, but the scene is three-dimensional"),
      std::string::npos)
      << message("ellipse_3d.gsd");
  EXPECT_NE(message("zero_q.gsd").find("is zero"), std::string::npos) << message("zero_q.gsd");
}

// A frame of `n` particles written chunk by chunk; `shapes` rows of
// type_shapes for the types `types`, and per-particle chunks of `rows` rows.
void write_typed_frame(pwcontact::GsdWriter& writer, std::uint32_t n,
                       const std::vector<std::string>& types, std::size_t shapes,
                       std::uint64_t rows) {
  writer.write("configuration/box", std::vector<float>{10, 10, 10, 0, 0, 0}, 6);
  writer.write("particles/N", std::vector<std::uint32_t>{n}, 1);
  writer.write("particles/types", types);
  std::vector<std::string> shape_rows;
  for (std::size_t t = 0; t < shapes; ++t)
    shape_rows.push_back(R"({"type": "Ellipsoid", "a": 1, "b": 0.5, "c": 0.25})");
  writer.write("particles/type_shapes", shape_rows);
  std::vector<std::uint32_t> type_ids(rows);
  for (std::size_t i = 0; i < rows; ++i) type_ids[i] = std::uint32_t(i % types.size());
  writer.write("particles/typeid", type_ids, rows);
  std::vector<float> position(3 * rows);
  for (std::size_t i = 0; i < rows; ++i) position[3 * i] = float(2 * i);
  writer.write("particles/position", position, rows);
}

TEST_F(GsdWritten, ChunksWithRowsThatDoNotFitTheFrameAreRefusedNamingThem) {
  auto write = [&](const std::string& name, const std::function<void(pwcontact::GsdWriter&)>& f) {
    std::ofstream out(directory_ / name, std::ios::binary);
    pwcontact::GsdWriter writer(out);
    f(writer);
    writer.finish();
    return (directory_ / name).string();
  };
  auto message = [](const std::string& path, std::int64_t frame = -1) {
    return message_of([&] { pwcontact::read_gsd(path, frame); });
  };
  // Fewer shapes than types (python3-gsd writes such a file for two types
  // and one shape): the shape of type 1 would be read beyond the chunk.
  const std::string few = write("few.gsd", [](pwcontact::GsdWriter& w) {
    write_typed_frame(w, 4, {"A", "B"}, 1, 4);
    w.end_frame();
  });
  EXPECT_NE(message(few).find("frame 0: particles/type_shapes has 1 rows for 2 types"),
            std::string::npos)
      << message(few);
  const std::string more = write("more.gsd", [](pwcontact::GsdWriter& w) {
    write_typed_frame(w, 4, {"A", "B"}, 3, 4);
    w.end_frame();
  });
  EXPECT_NE(message(more).find("frame 0: particles/type_shapes has 3 rows for 2 types"),
            std::string::npos)
      << message(more);
  // A later frame's own chunk is held to the frame's types (frame 0's here).
  const std::string later = write("later.gsd", [](pwcontact::GsdWriter& w) {
    write_typed_frame(w, 4, {"A", "B"}, 2, 4);
    w.end_frame();
    w.write("particles/type_shapes",
            std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})"});
    w.end_frame();
  });
  EXPECT_EQ(pwcontact::read_gsd(later, 0).particles.size(), 4u);
  EXPECT_NE(message(later, 1).find("frame 1: particles/type_shapes has 1 rows for 2 types"),
            std::string::npos)
      << message(later, 1);
  // Per-particle chunks of the frame with other than N rows.
  const std::string short_typeid = write("short_typeid.gsd", [](pwcontact::GsdWriter& w) {
    w.write("particles/N", std::vector<std::uint32_t>{4}, 1);
    w.write("particles/types", std::vector<std::string>{"A"});
    w.write("particles/type_shapes",
            std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})"});
    w.write("particles/typeid", std::vector<std::uint32_t>{0, 0, 0}, 3);
    w.end_frame();
  });
  EXPECT_NE(message(short_typeid).find("chunk particles/typeid of frame 0 is 3x1, expected 4x1"),
            std::string::npos)
      << message(short_typeid);
  const std::string short_q = write("short_orientation.gsd", [](pwcontact::GsdWriter& w) {
    write_typed_frame(w, 4, {"A"}, 1, 4);
    w.write("particles/orientation", std::vector<float>{1, 0, 0, 0, 1, 0, 0, 0}, 2);
    w.end_frame();
  });
  EXPECT_NE(message(short_q).find("chunk particles/orientation of frame 0 is 2x4, expected 4x4"),
            std::string::npos)
      << message(short_q);
}

// The schema's integers (N, dimensions, typeid) stored as another type are
// taken where they are whole numbers the schema's type holds, and refused
// naming the chunk, frame and row otherwise: a typeid of 2^32 + 1 was read
// as 1, of 0.9 as 0, a dimensions of 2.9 as 2, an N of 2.7 as 2, without a
// word. A bad shape's form names the file and frame; a name's bytes that
// are not printable are shown as \xHH; a pipe is refused by name.
TEST_F(GsdWritten, IntegersOfOtherTypesMustBeWholeNumbersTheSchemaHolds) {
  auto write = [&](const std::string& name, const std::function<void(pwcontact::GsdWriter&)>& f) {
    std::ofstream out(directory_ / name, std::ios::binary);
    pwcontact::GsdWriter writer(out);
    f(writer);
    writer.end_frame();
    writer.finish();
    return (directory_ / name).string();
  };
  auto message = [](const std::string& path) {
    return message_of([&] { pwcontact::read_gsd(path, -1); });
  };
  auto two_spheres = [](pwcontact::GsdWriter& w, const std::vector<std::string>& names) {
    w.write("configuration/box", std::vector<float>{10, 10, 10, 0, 0, 0}, 6);
    w.write("particles/types", names);
    w.write("particles/type_shapes",
            std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})",
                                     R"({"type": "Sphere", "diameter": 3})"});
    w.write("particles/position", std::vector<float>{0, 0, 0, 1.5, 0, 0}, 2);
  };
  const std::pair<std::string, std::function<void(pwcontact::GsdWriter&)>> cases[] = {
      {"chunk particles/typeid of frame 0, row 1: 4294967297 is not a whole number from 0 to "
       "4294967295",
       [&](pwcontact::GsdWriter& w) {
         w.write("particles/N", std::vector<std::uint32_t>{2}, 1);
         two_spheres(w, {"A", "B"});
         w.write("particles/typeid", std::vector<std::uint64_t>{0, (std::uint64_t(1) << 32) + 1},
                 2);
       }},
      {"chunk particles/typeid of frame 0, row 1: 0.9 is not a whole number",
       [&](pwcontact::GsdWriter& w) {
         w.write("particles/N", std::vector<std::uint32_t>{2}, 1);
         two_spheres(w, {"A", "B"});
         w.write("particles/typeid", std::vector<double>{0, 0.9}, 2);
       }},
      {"chunk configuration/dimensions of frame 0, row 0: 2.9 is not a whole number",
       [&](pwcontact::GsdWriter& w) {
         w.write("particles/N", std::vector<std::uint32_t>{2}, 1);
         w.write("configuration/dimensions", std::vector<double>{2.9}, 1);
         two_spheres(w, {"A", "B"});
       }},
      {"chunk particles/N of frame 0, row 0: 2.7 is not a whole number",
       [&](pwcontact::GsdWriter& w) {
         w.write("particles/N", std::vector<double>{2.7}, 1);
         two_spheres(w, {"A", "B"});
       }},
      {"frame 0: particles/type_shapes, type 1 ('B\\x1B[2J'): ",
       [&](pwcontact::GsdWriter& w) {
         w.write("particles/N", std::vector<std::uint32_t>{2}, 1);
         w.write("configuration/box", std::vector<float>{10, 10, 10, 0, 0, 0}, 6);
         w.write("particles/types", std::vector<std::string>{"A", "B\x1b[2J"});
         w.write("particles/type_shapes",
                 std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})",
                                          R"({"type": "Ellipsoid", "a": 1, "b": 1, "c": 1e-170})"});
         w.write("particles/position", std::vector<float>{0, 0, 0, 1.5, 0, 0}, 2);
       }},
  };
  int k = 0;
  for (const auto& [expected, fill] : cases) {
    const std::string path = write("integers" + std::to_string(k++) + ".gsd", fill);
    const std::string got = message(path);
    EXPECT_NE(got.find(path + ": "), std::string::npos) << got;
    EXPECT_NE(got.find(expected), std::string::npos) << got;
  }
  // The same numbers as whole numbers of other types are taken.
  const std::string whole = write("whole.gsd", [&](pwcontact::GsdWriter& w) {
    w.write("particles/N", std::vector<double>{2}, 1);
    two_spheres(w, {"A", "B"});
    w.write("particles/typeid", std::vector<double>{0, 1}, 2);
  });
  const Scene scene = pwcontact::read_gsd(whole, -1);
  ASSERT_EQ(scene.particles.size(), 2u);
  EXPECT_EQ(scene.particles.sphere_radius()[1], 1.5);
  // type_shapes is JSON: its escapes are JSON's ("Ellips\u006fid" is an
  // Ellipsoid; it was read as "Ellipsu006fid"), and what JSON does not
  // allow is refused ("\o", a number "01"; both were taken).
  auto shaped = [&](const std::string& name, const std::string& json) {
    return write(name, [&](pwcontact::GsdWriter& w) {
      w.write("particles/N", std::vector<std::uint32_t>{1}, 1);
      w.write("configuration/box", std::vector<float>{10, 10, 10, 0, 0, 0}, 6);
      w.write("particles/types", std::vector<std::string>{"A"});
      w.write("particles/type_shapes", std::vector<std::string>{json});
      w.write("particles/position", std::vector<float>{0, 0, 0}, 1);
    });
  };
  const Scene escaped = pwcontact::read_gsd(
      shaped("escaped.gsd", R"({"type": "Ellips\u006fid", "\u0061": 2, "b": 1, "c": 0.5})"), -1);
  EXPECT_EQ(escaped.particles.bounding_radius()[0] > 1.99, true);
  EXPECT_NE(message(shaped("bad_escape.gsd", R"({"type": "Ellips\oid", "a": 1, "b": 1, "c": 1})"))
                .find("an escape JSON does not have"),
            std::string::npos);
  EXPECT_NE(message(shaped("leading_zero.gsd", R"({"type": "Sphere", "diameter": 01})"))
                .find("not a number in JSON's grammar"),
            std::string::npos);
  // A pipe has no size and no offsets: refused by name (it was read as a
  // file of 0 bytes).
  const std::string pipe = (directory_ / "pipe.gsd").string();
  ASSERT_EQ(mkfifo(pipe.c_str(), 0600), 0);
  EXPECT_NE(message(pipe).find("not a regular file"), std::string::npos) << message(pipe);
}

TEST_F(GsdWritten, AHugeParticleCountIsCheckedAgainstTheChunksBeforeAnythingIsAllocated) {
  // particles/N = 2^31 - 1 with chunks of 4 rows: refused naming the chunk
  // (not 3 N doubles of positions allocated first, 51 GB).
  auto huge = [&](const std::string& name, bool with_position, bool with_typeid = true) {
    std::ofstream out(directory_ / name, std::ios::binary);
    pwcontact::GsdWriter writer(out);
    writer.write("particles/N", std::vector<std::uint32_t>{0x7fffffffu}, 1);
    writer.write("particles/types", std::vector<std::string>{"A"});
    writer.write("particles/type_shapes",
                 std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})"});
    if (with_position) writer.write("particles/position", std::vector<float>(12, 0.0f), 4);
    if (with_typeid) writer.write("particles/typeid", std::vector<std::uint32_t>(4, 0), 4);
    writer.end_frame();
    writer.finish();
    return (directory_ / name).string();
  };
  const std::string with_position = huge("position.gsd", true);
  const std::string message = message_of([&] { pwcontact::read_gsd(with_position); });
  EXPECT_NE(message.find("chunk particles/position of frame 0 is 4x3, expected 2147483647x3"),
            std::string::npos)
      << message;
  const std::string typeid_only = huge("typeid.gsd", false);
  const std::string typeid_message = message_of([&] { pwcontact::read_gsd(typeid_only); });
  EXPECT_NE(typeid_message.find("chunk particles/typeid of frame 0 is 4x1, expected 2147483647x1"),
            std::string::npos)
      << typeid_message;
  // No per-particle chunk at all: the schema's defaults would put 2^31 - 1
  // particles at the origin, and their arrays exhausted memory. Refused.
  const std::string bare = huge("bare.gsd", false, false);
  const std::string bare_message = message_of([&] { pwcontact::read_gsd(bare); });
  EXPECT_NE(bare_message.find("2147483647 particles but no particles/position"), std::string::npos)
      << bare_message;
}

TEST_F(GsdWritten, AChunkOfStringsWithRowsOfNoCharactersIsRefused) {
  // particles/types made 10^12 rows of 0 characters (in the index, after
  // writing): they take no bytes, so the file's size does not bound them.
  const fs::path path = directory_ / "empty_rows.gsd";
  {
    std::ofstream out(path, std::ios::binary);
    pwcontact::GsdWriter writer(out);
    writer.write("particles/N", std::vector<std::uint32_t>{1}, 1);
    writer.write("particles/types", std::vector<std::string>{"A"});
    writer.write("particles/type_shapes",
                 std::vector<std::string>{R"({"type": "Sphere", "diameter": 1})"});
    writer.end_frame();
    writer.finish();
  }
  std::fstream file(path, std::ios::binary | std::ios::in | std::ios::out);
  std::uint64_t index = 0;
  file.seekg(8);  // the header's index_location
  file.read(reinterpret_cast<char*>(&index), sizeof index);
  // Entries of 32 bytes: frame, N, location, M (uint32), id (uint16), ...;
  // the names in the order written, particles/types the second.
  bool patched = false;
  for (std::uint64_t at = index; !patched; at += 32) {
    std::int64_t location = 0;
    std::uint16_t id = 0;
    file.seekg(std::streamoff(at + 16));
    file.read(reinterpret_cast<char*>(&location), sizeof location);
    file.seekg(std::streamoff(at + 28));
    file.read(reinterpret_cast<char*>(&id), sizeof id);
    ASSERT_TRUE(file && location != 0) << "no index entry of particles/types";
    if (id != 1) continue;
    const std::uint64_t rows = 1000000000000;
    const std::uint32_t columns = 0;
    file.seekp(std::streamoff(at + 8));
    file.write(reinterpret_cast<const char*>(&rows), sizeof rows);
    file.seekp(std::streamoff(at + 24));
    file.write(reinterpret_cast<const char*>(&columns), sizeof columns);
    patched = true;
  }
  file.close();
  // (Refused before any name is made: the rows against type_shapes' first,
  // which this file's one shape does not match; the names' own check, rows
  // of no characters, where type_shapes would match them.)
  const std::string message = message_of([&] { pwcontact::read_gsd(path.string()); });
  EXPECT_TRUE(
      message.find("chunk particles/types of frame 0 has 1000000000000 rows of no characters") !=
          std::string::npos ||
      message.find("frame 0: particles/type_shapes has 1 rows for 1000000000000 types") !=
          std::string::npos)
      << message;
}

// ---------------------------------------------------------------------------
// LAMMPS

TEST(SceneFiles, ALammpsDataFileOfEllipsoidsInATriclinicBox) {
  // tests/data/lammps_triclinic.in: region prism 0 8 0 7 0 6, tilts 1.2 -0.9
  // 0.6 (lengths), 30 atoms of type 1 with shape (diameters) 1.2 0.8 0.6 and
  // 20 of type 2 with 0.9 0.9 0.9.
  const Scene scene = pwcontact::read_lammps_data((data_dir / "lammps_triclinic.data").string());
  ASSERT_EQ(scene.particles.size(), 50u);
  EXPECT_EQ(scene.box.length, (std::array<double, 3>{8, 7, 6}));
  EXPECT_DOUBLE_EQ(scene.box.tilt[0], 1.2 / 7);
  EXPECT_DOUBLE_EQ(scene.box.tilt[1], -0.9 / 6);
  EXPECT_DOUBLE_EQ(scene.box.tilt[2], 0.6 / 6);
  for (std::size_t i = 0; i < 50; ++i) {
    EXPECT_EQ(scene.id[i], i + 1);
    if (scene.type_id[i] == 0)
      expect_radii(scene, i, 0.6, 0.3, "shape 1.2 0.8 0.6 (diameters)");
    else
      expect_radii(scene, i, 0.45, 0.45, "shape 0.9 0.9 0.9");
  }
  expect_screen_matches_brute_force(scene, 1.3, "LAMMPS data, triclinic");
}

TEST(SceneFiles, ALammpsDumpsFramesWithTheBoundingBoxConvertedBack) {
  const std::string path = (data_dir / "lammps_triclinic.dump").string();
  const Scene data = pwcontact::read_lammps_data((data_dir / "lammps_triclinic.data").string());
  // The shapes and orientations under the compute's names.
  pwcontact::LammpsColumns columns;
  for (int k = 0; k < 3; ++k) columns.shape[k] = "c_s[" + std::to_string(k + 1) + "]";
  for (int k = 0; k < 4; ++k) columns.quaternion[k] = "c_q[" + std::to_string(k + 1) + "]";
  const Scene first = pwcontact::read_lammps_dump(path, 0, columns);
  const Scene last = pwcontact::read_lammps_dump(path, -1, columns);
  EXPECT_EQ(first.frames, 3u);
  EXPECT_EQ(last.frame, 2u);
  // The bounding box of the dump back to the data file's box.
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(first.box.length[k], data.box.length[k], 1e-12);
    EXPECT_NEAR(first.box.tilt[k], data.box.tilt[k], 1e-12);
  }
  for (std::size_t i = 0; i < 50; ++i) {
    // Frame 0 is the data file's scene (positions with 6 digits).
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(first.particles.centre(k)[i], data.particles.centre(k)[i], 1e-4);
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(first.particles.q(k)[i], data.particles.q(k)[i], 1e-5);
    // Each frame moved by (0.1, 0.2, 0.3), and LAMMPS wrapped the atoms that
    // left the box: what remains of the displacement is a lattice vector
    // (integer fractional coordinates under h^-1, h upper triangular).
    double d[3];
    for (int k = 0; k < 3; ++k)
      d[k] = last.particles.centre(k)[i] - first.particles.centre(k)[i] - 0.2 * (k + 1);
    const auto& b = last.box;
    const double s2 = d[2] / b.length[2];
    const double s1 = (d[1] - b.tilt[2] * b.length[2] * s2) / b.length[1];
    const double s0 =
        (d[0] - b.tilt[0] * b.length[1] * s1 - b.tilt[1] * b.length[2] * s2) / b.length[0];
    for (double s : {s0, s1, s2}) EXPECT_NEAR(s, std::round(s), 1e-4) << "atom " << i + 1;
  }
  expect_screen_matches_brute_force(last, 1.3, "LAMMPS dump, last frame");
  // Without the column names: the usual ones are looked for, and named.
  EXPECT_NE(message_of([&] { pwcontact::read_lammps_dump(path); }).find("no column shapex"),
            std::string::npos);
}

TEST(SceneFiles, MalformedLammpsFilesNameTheirLine) {
  std::string pattern = (fs::path(::testing::TempDir()) / "pwcontact_lammps.XXXXXX").string();
  ASSERT_NE(mkdtemp(pattern.data()), nullptr);
  const fs::path dir = pattern;
  std::ifstream in(data_dir / "lammps_triclinic.data");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  auto write_with = [&](const std::string& name, std::size_t line_index,
                        const std::string& replacement) {
    std::ofstream out(dir / name);
    for (std::size_t k = 0; k < lines.size(); ++k)
      out << (k == line_index ? replacement : lines[k]) << "\n";
    return (dir / name).string();
  };
  std::size_t atoms = 0, ellipsoids = 0;
  for (std::size_t k = 0; k < lines.size(); ++k) {
    if (lines[k].rfind("Atoms", 0) == 0) atoms = k;
    if (lines[k].rfind("Ellipsoids", 0) == 0) ellipsoids = k;
  }
  auto message = [](const std::string& path) {
    return message_of([&] { pwcontact::read_lammps_data(path); });
  };
  const std::string point = write_with("point.data", atoms + 2, "1 1 0 3.3 1 1 1 0 0 0");
  EXPECT_NE(message(point).find(":" + std::to_string(atoms + 3) + ": atom 1 has ellipsoidflag 0"),
            std::string::npos)
      << message(point);
  const std::string short_line = write_with("short.data", ellipsoids + 2, "1 1.2 0.8 0.6 1 0 0");
  EXPECT_NE(message(short_line)
                .find(":" + std::to_string(ellipsoids + 3) + ": an Ellipsoids line has 8 fields"),
            std::string::npos)
      << message(short_line);
  const std::string zero = write_with("zero.data", ellipsoids + 2, "1 1.2 0 0.6 1 0 0 0");
  EXPECT_NE(message(zero).find("atom 1: "), std::string::npos) << message(zero);
  // Atoms of two Ellipsoids lines, or none: the line, or the atom's Atoms line.
  const std::string twice = write_with("twice.data", ellipsoids + 3, "1 1.2 0.8 0.6 1 0 0 0");
  EXPECT_NE(message(twice).find(":" + std::to_string(ellipsoids + 4) +
                                ": atom 1 has a second Ellipsoids line (the first is line " +
                                std::to_string(ellipsoids + 3) + ")"),
            std::string::npos)
      << message(twice);
  const std::string none = write_with("none.data", ellipsoids + 3, "");
  EXPECT_NE(message(none).find(":" + std::to_string(atoms + 4) + ": atom 2 has no Ellipsoids line"),
            std::string::npos)
      << message(none);
  // Every field of an Atoms line is parsed and checked, as LAMMPS does.
  const std::string atom_line = ":" + std::to_string(atoms + 3) + ": ";
  const std::pair<const char*, const char*> bad_fields[] = {
      {"1 1 1 abc 1 5 5", "the density 'abc' is not a finite number"},
      {"1 1 1 0 1 5 5", "atom 1 has density 0: LAMMPS requires a positive density"},
      {"1 1 1 -2.5 1 5 5 0 0 0", "atom 1 has density -2.5"},
      {"1 1 2 1 1 5 5", "atom 1 has ellipsoidflag 2, not 0 or 1"},
      {"1 1 1 1 1 5 5 a b c", "the image flag 'a' is not an integer"},
      {"1 1 1 1 1 5 5 0 1.5 0", "the image flag '1.5' is not an integer"},
      {"0 1 1 1 1 5 5", "atom id 0: LAMMPS atom ids are positive"},
      // ('+' before a number, not before a sign: "+-1" was read as -1.)
      {"1 1 1 1 +-1 5 5", "a coordinate '+-1' is not a finite number"},
      {"1 1 1 1 1 5 5 0 +-1 0", "the image flag '+-1' is not an integer"},
      // (A file's bytes in a message as \xHH: an escape sequence no more
      // acts on the terminal.)
      {"1 1 1 \x1b[2J 1 5 5", "the density '\\x1B[2J' is not a finite number"},
  };
  for (const auto& [replacement, expected] : bad_fields) {
    const std::string bad = write_with("field.data", atoms + 2, replacement);
    EXPECT_NE(message(bad).find(atom_line + expected), std::string::npos)
        << replacement << ": " << message(bad);
  }
  // The header's box and count lines, malformed, name their line: a line
  // that begins with a word is one of them by its keywords, not the name
  // of a section (a tilt line "nan 0 0 xy xz yz" was so skipped, and the
  // box read as orthogonal).
  std::size_t tilts = 0, bounds = 0, count = 0;
  for (std::size_t k = 0; k < lines.size(); ++k) {
    if (lines[k].find("xy xz yz") != std::string::npos) tilts = k;
    if (lines[k].find("ylo yhi") != std::string::npos) bounds = k;
    if (lines[k].find(" atoms") != std::string::npos) count = k;
  }
  ASSERT_GT(tilts, 0u);
  const std::pair<std::size_t, const char*> bad_header[][2] = {
      {{tilts, "nan 0 0 xy xz yz"}, {tilts, "a tilt 'nan' is not a finite number"}},
      {{tilts, "abc 0 0 xy xz yz"}, {tilts, "a tilt 'abc' is not a finite number"}},
      {{tilts, "inf 0 0 xy xz yz"}, {tilts, "a tilt 'inf' is not a finite number"}},
      {{tilts, "4.0 0 xy xz yz"},
       {tilts, "a header line 'xy xz yz' has 3 numbers before its keywords, this one 2"}},
      {{tilts, "1 4.0 0 0 xy xz yz"},
       {tilts, "a header line 'xy xz yz' has 3 numbers before its keywords, this one 4"}},
      {{tilts, "2.0 0 0 XY XZ YZ"},
       {tilts, "the header keywords 'xy xz yz' are written in another case"}},
      {{bounds, "nan 10 ylo yhi"}, {bounds, "ylo 'nan' is not a finite number"}},
      {{bounds, "0 ylo yhi"},
       {bounds, "a header line 'ylo yhi' has 2 numbers before its keywords, this one 1"}},
      {{count, "fifty atoms"}, {count, "the atom count 'fifty' is not a whole number"}},
  };
  for (const auto& [change, expected] : bad_header) {
    const std::string bad = write_with("header.data", change.first, change.second);
    EXPECT_NE(message(bad).find(":" + std::to_string(expected.first + 1) + ": " + expected.second),
              std::string::npos)
        << change.second << ": " << message(bad);
  }
  // Image flags of any sign are integers.
  const Scene imaged = pwcontact::read_lammps_data(
      write_with("imaged.data", atoms + 2,
                 "1 1 1 3.3157279810811535 8.423517774475513 6.744612934228318 "
                 "2.1391465068511417 -1 +2 0"));
  EXPECT_EQ(imaged.particles.size(), 50u);
  fs::remove_all(dir);
}

TEST(SceneFiles, MalformedLammpsDumpsNameTheirLine) {
  std::string pattern = (fs::path(::testing::TempDir()) / "pwcontact_dump.XXXXXX").string();
  ASSERT_NE(mkdtemp(pattern.data()), nullptr);
  const fs::path dir = pattern;
  // A frame of `count` (as written) and its atom lines, each "id x".
  auto frame = [](const std::string& count, const std::vector<std::string>& atoms) {
    std::string text = "ITEM: TIMESTEP\n0\n";
    if (!count.empty()) text += "ITEM: NUMBER OF ATOMS\n" + count + "\n";
    text +=
        "ITEM: BOX BOUNDS pp pp pp\n0 10\n0 10\n0 10\n"
        "ITEM: ATOMS id type x y z shapex shapey shapez quatw quati quatj quatk\n";
    for (const std::string& a : atoms) {
      std::istringstream in(a);
      std::string id, x;
      in >> id >> x;
      text += id + " 1 " + x + " 5 5 2 2 2 1 0 0 0\n";
    }
    return text;
  };
  auto message = [&](const std::string& name, const std::string& text, std::int64_t f = -1) {
    std::ofstream(dir / name) << text;
    return message_of([&] { pwcontact::read_lammps_dump((dir / name).string(), f); });
  };
  // (Lines 1-9 the frame's items, its atoms from line 10.)
  const std::string good = frame("2", {"1 1", "2 5"});
  std::ofstream(dir / "good.dump") << good << good;
  EXPECT_EQ(pwcontact::read_lammps_dump((dir / "good.dump").string(), 0).particles.size(), 2u);
  EXPECT_EQ(pwcontact::read_lammps_dump((dir / "good.dump").string(), 1).particles.size(), 2u);
  // More atom lines than the count.
  const std::string extra = message("extra.dump", frame("2", {"1 1", "2 5", "3 9.5"}));
  EXPECT_NE(extra.find(":12: frame 0: more atom lines than ITEM: NUMBER OF ATOMS gives (2)"),
            std::string::npos)
      << extra;
  const std::string extra_first =
      message("extra_first.dump", frame("2", {"1 1", "2 5", "3 9.5"}) + good, 0);
  EXPECT_NE(extra_first.find(":12: frame 0: more atom lines"), std::string::npos) << extra_first;
  // No count.
  const std::string uncounted = message("uncounted.dump", good + frame("", {"1 1", "2 5"}));
  EXPECT_NE(uncounted.find(":18: frame 1: no ITEM: NUMBER OF ATOMS before ITEM: ATOMS"),
            std::string::npos)
      << uncounted;
  // An id twice.
  const std::string twice = message("twice.dump", frame("3", {"1 1", "2 5", "1 9.5"}));
  EXPECT_NE(twice.find(":12: frame 0: atom id 1 appears twice (first on line 10)"),
            std::string::npos)
      << twice;
  // Fewer atom lines than the count: at the end of the file, or before the
  // next frame; a count no file could hold is not reserved.
  const std::string short_last = message("short_last.dump", frame("3", {"1 1", "2 5"}));
  EXPECT_NE(short_last.find("frame 0: the frame ends after 2 of its 3 atoms"), std::string::npos)
      << short_last;
  const std::string short_first = message("short_first.dump", frame("3", {"1 1", "2 5"}) + good, 0);
  EXPECT_NE(short_first.find(":12: frame 0: the frame ends after 2 of its 3 atoms"),
            std::string::npos)
      << short_first;
  // A shape the store refuses (a zero semi-axis) in the second frame: named
  // as the reader names its own errors, "file:line: frame F: ...".
  std::string flat = frame("2", {"1 1", "2 5"});
  flat.replace(flat.rfind(" 2 2 2 "), 7, " 0 2 2 ");
  const std::string refused = message("refused.dump", good + flat, 1);
  EXPECT_NE(refused.find(":22: frame 1: atom 2:"), std::string::npos) << refused;
  const std::string huge = message("huge.dump", frame("1000000000000000000", {"1 1", "2 5"}));
  EXPECT_NE(huge.find("the frame ends after 2 of its 1000000000000000000 atoms"), std::string::npos)
      << huge;
  // Scaled coordinates mapped as positions: refused (read as lengths, they
  // put every particle within a unit of the origin; was: 2849 false pairs).
  std::string scaled = good;
  scaled.replace(scaled.find("x y z"), 5, "xs ys zs");
  std::ofstream(dir / "scaled.dump") << scaled;
  pwcontact::LammpsColumns columns;
  for (int k = 0; k < 3; ++k) columns.position[k] = std::string(1, char('x' + k)) + "s";
  const std::string scaled_message =
      message_of([&] { pwcontact::read_lammps_dump((dir / "scaled.dump").string(), 0, columns); });
  EXPECT_NE(scaled_message.find("column xs holds scaled coordinates"), std::string::npos)
      << scaled_message;
  // A dump is read twice (its frames found, then one read): a named pipe is
  // refused by name, where the second read hung.
  const std::string pipe = (dir / "pipe.dump").string();
  ASSERT_EQ(mkfifo(pipe.c_str(), 0600), 0);
  const std::string pipe_message = message_of([&] { pwcontact::read_lammps_dump(pipe, 0); });
  EXPECT_NE(pipe_message.find("not a regular file"), std::string::npos) << pipe_message;
  fs::remove_all(dir);
}

}  // namespace
