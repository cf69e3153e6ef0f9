// accura post-processor: the robot cell (docs/cell-format.md): CAD meshes of the fixtures and
// parts placed in the world, where the robot stands, the geometry of the robot's links and
// tool, and the thresholds of the reach and clearance checks (check.h).
//
// Units: mm and deg at this interface (meshes are scaled to mm when they are read, from the
// unit the cell file gives them). Frames: T_a_b maps frame b coordinates to frame a.
//   world      the cell frame (the calibrated model's world; see job.h)
//   object     the frame a mesh file's coordinates are in, placed by T_world_object
//   link i     DH frame i of the robot (i = 1..n; frame i moves with joints 1..i, frame n is
//              the flange), as calib's forwardKinematics computes it
//              (KinematicWorkspace::T_base_frame[i]); the tool is in the flange frame.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <optional>
#include <string>
#include <vector>

namespace accura::postproc {

/// The largest coordinate, distance or size the cell accepts (mm): 100 m, beyond any robot
/// cell. Larger values are unit mistakes or garbage, and they break the distance queries
/// (FCL's GJK asserts on a capsule at 1e300 mm; a 2,000 km tool capsule makes the clearance
/// subdivision run for minutes). Applies to mesh vertices (once scaled to mm), placements
/// (x_mm, y_mm, z_mm), capsule end points and radii, and min_clearance_mm.
inline constexpr double kMaxCellExtent_mm = 1e5;
/// The largest placement angle (a_deg, b_deg, c_deg) the cell accepts, in magnitude (deg).
inline constexpr double kMaxCellAngle_deg = 360;

/// A triangle mesh (mm) in its own frame.
/// A mesh less than this across (mm) is reported by the checks as a likely unit mistake (a
/// file in metres given units="mm"; below 1 mm loadMesh refuses it).
inline constexpr double kSmallMesh_mm = 10.0;

struct Mesh {
  std::vector<Eigen::Vector3d> vertices_mm;
  std::vector<std::array<int, 3>> triangles;  ///< vertex indices, counter-clockwise
  std::string file;                           ///< where it was read from (messages)
};

/// Reads every triangle of every mesh of a file assimp can read (STL, OBJ, PLY, 3MF, glTF,
/// COLLADA, ...; the scene's node transforms are applied) and multiplies the coordinates by
/// `scale_to_mm` (1 for mm, 1000 for m, 25.4 for inch). Polygons are triangulated; points and
/// lines are ignored. PLY (ASCII and binary), STL (ASCII and binary) and OBJ files are checked
/// completely before assimp reads them: a truncated or half-read file (a missing declared
/// element, an ASCII STL without endfacet/endsolid, an OBJ whose last line is cut), a face
/// index beyond the vertices, a number that is not a finite decimal are errors with the
/// file's line and column (binary files: the byte offset), not a smaller mesh. Every format's
/// scene is checked (face indices, node mesh indices, finite transforms) before assimp's
/// post-processing runs on it. Throws InputError naming the file when the file is malformed,
/// when assimp cannot read it, when it holds no triangle, or when a coordinate is not finite
/// or lies beyond kMaxCellExtent_mm (in mm, after scaling); ArgumentError when scale_to_mm is
/// not a positive finite number.
Mesh loadMesh(const std::string& path, double scale_to_mm);

/// A capsule: the points within radius_mm of the segment p0_mm-p1_mm (a sphere when the two
/// coincide). Coordinates in the frame of the CellShape that holds it (mm).
struct Capsule {
  Eigen::Vector3d p0_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d p1_mm = Eigen::Vector3d::Zero();
  double radius_mm = 0;
};

/// One piece of geometry: a mesh or a capsule (exactly one of the two), in the shape's frame,
/// placed in its parent frame (world for objects, DH frame i for links, flange for the tool).
struct CellShape {
  std::optional<Mesh> mesh;
  std::optional<Capsule> capsule;
  Eigen::Isometry3d T_parent_shape = Eigen::Isometry3d::Identity();
  std::string name;  ///< for reports: "table", "link 3", "tool", ...
  std::string file;  ///< the cell file
  int line = 0;      ///< of its element in the cell file (1-based; 0: not from a file)
  int column = 0;    ///< of its element's '<' on that line (1-based, bytes; 0: unknown)
};

/// Thresholds of the checks (check.h), with their defaults.
struct CheckThresholds {
  /// Required distance of every joint from its limits: deg (revolute), mm (prismatic).
  double joint_margin_deg = 1.0;
  /// Smallest singular value of the scaled joint Jacobian (dimensionless; docs/checks.md):
  /// 0.005 is A5 within about 1.1 deg of 0 on a KR 16.
  double singular_threshold = 0.005;
  /// Required distance between the robot (links and tool) and every cell mesh (mm).
  double min_clearance_mm = 5.0;
};

struct Cell {
  std::string file;  ///< the cell file
  /// Obstacles: fixtures, parts, fences (parent frame: world).
  std::vector<CellShape> objects;
  /// Where the robot stands in the cell (nominal T_world_base, the placement the OLP used);
  /// empty when the cell file does not say (the robot file's <base> or --base is used).
  std::optional<Eigen::Isometry3d> T_world_base;
  /// Where the <robot> element is in the cell file (1-based line and column of its '<'; 0:
  /// not from a file), for the message when it disagrees with --base.
  int robot_line = 0, robot_column = 0;
  /// Robot geometry: link_shapes[k].first is the DH frame index (1..n) the shape moves with.
  std::vector<std::pair<int, CellShape>> link_shapes;
  /// Where the `joint` attribute of link_shapes[k]'s <link> is in the cell file (1-based line
  /// and column of its name; parallel to link_shapes, empty or {0, 0} when not from a file): a
  /// joint the robot does not have is only known against the robot (CellGeometry), and is an
  /// error of the cell file there.
  std::vector<std::pair<int, int>> link_joint_positions;
  /// Tool geometry in the flange frame (frame n).
  std::vector<CellShape> tool_shapes;
  CheckThresholds thresholds;
};

/// Reads a cell file (docs/cell-format.md). Mesh paths are relative to the cell file's
/// directory. Throws InputError with file:line:column and what was expected and found for a
/// malformed file (tinyxml2 gives its line only: column 0), an unknown element or attribute, a missing one, a bad number
/// (anything but a finite decimal, e.g. blank, hex, 1e309) or unit, a coordinate, capsule radius
/// or min_clearance_mm beyond kMaxCellExtent_mm, an angle beyond kMaxCellAngle_deg, and
/// for a mesh file assimp cannot read or without triangles (naming that file). Link indices
/// are checked against the robot by the checks (check.h), not here. The column (1-based, in
/// bytes) is that of the attribute's name for an error in an attribute, of the element's '<'
/// for an error in an element (tinyxml2 gives lines only: the reader finds the columns in the
/// file's text).
Cell readCellFile(const std::string& path);

}  // namespace accura::postproc
