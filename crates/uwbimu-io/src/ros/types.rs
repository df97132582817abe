//! ROS 2 message definitions for a live graph: the `.msg` texts of the standard types the node
//! reads and writes (bundled), the lookup of any other type in `.msg` folders laid out as a ROS 2
//! workspace (`<dir>/<pkg>/msg/<Type>.msg`), and the DDS names ROS 2 gives them.
//!
//! [`full_definition`] gives the text an MCAP `ros2msg` schema carries (the type's own `.msg`,
//! then a line of `=` and `MSG: pkg/msg/Type` with each dependency), which both
//! [`crate::ros::msg_schema::MsgSchema::parse`] and a DDS type builder read.

use std::path::{Path, PathBuf};

use crate::mapping::topics::SENSORS;
use crate::ros::msg_schema::{nested_type_names, normalize};
use uwbimu_vocabulary::error::Error as CoreError;

use crate::{IoError as Error, IoResult as Result};

/// The bundled `.msg` texts, by normalised name (`pkg/Type`): what the node reads (IMU, range,
/// odometry, our TDoA and anchor-range messages) and writes (pose, odometry, diagnostics); the
/// sensors' io rows bundle the types only they read ([`SensorIo::definitions`](crate::mapping::topics::SensorIo::definitions)).
const BUNDLED: &[(&str, &str)] = &[
    ("std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id\n"),
    ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n"),
    ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n"),
    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
    ("geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"),
    ("geometry_msgs/Pose", "Point position\nQuaternion orientation\n"),
    ("geometry_msgs/PoseWithCovariance", "Pose pose\nfloat64[36] covariance\n"),
    ("geometry_msgs/PoseWithCovarianceStamped", "std_msgs/Header header\nPoseWithCovariance pose\n"),
    ("geometry_msgs/PoseStamped", "std_msgs/Header header\nPose pose\n"),
    ("geometry_msgs/Twist", "Vector3 linear\nVector3 angular\n"),
    ("geometry_msgs/TwistWithCovariance", "Twist twist\nfloat64[36] covariance\n"),
    (
        "sensor_msgs/Imu",
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n\
         geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n\
         geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
    ),
    (
        "sensor_msgs/Range",
        "uint8 ULTRASOUND=0\nuint8 INFRARED=1\nstd_msgs/Header header\nuint8 radiation_type\nfloat32 field_of_view\n\
         float32 min_range\nfloat32 max_range\nfloat32 range\n",
    ),
    (
        "nav_msgs/Odometry",
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
         geometry_msgs/TwistWithCovariance twist\n",
    ),
    ("diagnostic_msgs/KeyValue", "string key\nstring value\n"),
    (
        "diagnostic_msgs/DiagnosticStatus",
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\n\
         string hardware_id\nKeyValue[] values\n",
    ),
    ("diagnostic_msgs/DiagnosticArray", "std_msgs/Header header\nDiagnosticStatus[] status\n"),
    ("uwbimu_msgs/UwbRange", "std_msgs/Header header\nstring anchor_id\nfloat64 range\nfloat64 variance\nstring tag\n"),
    ("uwbimu_msgs/Tdoa", "std_msgs/Header header\nstring idA\nstring idB\nfloat64 distanceDiff\n"),
    ("uwbimu_msgs/AnchorRange", "std_msgs/Header header\nstring anchor_i\nstring anchor_j\nfloat64 range\n"),
];

/// The `.msg` text of one type (no dependency sections): bundled (here, or by a sensor's io
/// row, [`SensorIo::definitions`](crate::mapping::topics::SensorIo::definitions)), else the first `<dir>/<pkg>/msg/<Type>.msg` (or
/// `<dir>/<Type>.msg`) of `msg_paths`.
fn own_definition(name: &str, msg_paths: &[PathBuf]) -> Result<String> {
    let sensors = SENSORS.iter().flat_map(|row| row.definitions());
    if let Some((_, text)) = BUNDLED.iter().chain(sensors).find(|(n, _)| *n == name) {
        return Ok(text.lines().map(str::trim).collect::<Vec<_>>().join("\n") + "\n");
    }
    let (pkg, ty) = name.split_once('/').unwrap_or(("", name));
    let candidates = |dir: &Path| [dir.join(pkg).join("msg").join(format!("{ty}.msg")), dir.join(format!("{ty}.msg"))];
    for path in msg_paths.iter().flat_map(|d| candidates(d)) {
        if path.is_file() {
            return std::fs::read_to_string(&path).map_err(|e| Error::io(path.display().to_string(), e));
        }
    }
    let searched: Vec<String> = msg_paths.iter().map(|p| p.display().to_string()).collect();
    Err(CoreError::InvalidConfig {
        field: "live.msg_paths".into(),
        reason: format!("no definition of `{name}`: not bundled, and no {pkg}/msg/{ty}.msg under [{}]", searched.join(", ")),
    }
    .into())
}

/// The whole definition of the type `name` (`pkg/msg/Type` or `pkg/Type`) as an MCAP `ros2msg`
/// schema carries it: its own `.msg` text, then each type it uses, directly or not, after a line
/// of 80 `=` and `MSG: pkg/msg/Type`. Each type is bundled, else read from the first
/// `<dir>/<pkg>/msg/<Type>.msg` (or `<dir>/<Type>.msg`) of `msg_paths`.
///
/// # Errors
/// [`Error::Mapping`] for a type found nowhere; [`Error::Format`] for an unparsable definition.
pub fn full_definition(name: &str, msg_paths: &[PathBuf]) -> Result<String> {
    let root = normalize(name);
    let mut text = own_definition(&root, msg_paths)?;
    let mut queue = vec![(root.clone(), text.clone())];
    let mut seen = vec![root];
    while let Some((type_name, body)) = queue.pop() {
        for dep in nested_type_names(&type_name, &body)? {
            if seen.contains(&dep) {
                continue;
            }
            let dep_text = own_definition(&dep, msg_paths)?;
            let (pkg, ty) = dep.split_once('/').unwrap_or(("", &dep));
            text.push_str(&format!("{}\nMSG: {pkg}/msg/{ty}\n{dep_text}", "=".repeat(80)));
            if !dep_text.ends_with('\n') {
                text.push('\n');
            }
            seen.push(dep.clone());
            queue.push((dep, dep_text));
        }
    }
    Ok(text)
}

/// The DDS type name ROS 2 gives the type `pkg/msg/Type` (or `pkg/Type`):
/// `pkg::msg::dds_::Type_`.
pub fn dds_type_name(name: &str) -> String {
    let n = normalize(name);
    let (pkg, ty) = n.split_once('/').unwrap_or(("", &n));
    format!("{pkg}::msg::dds_::{ty}_")
}

/// The DDS topic name ROS 2 gives the topic `/name`: `rt/name`.
pub fn dds_topic_name(topic: &str) -> String {
    format!("rt/{}", topic.trim_start_matches('/'))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recordings::recording_out::IMU_MSG;
    use crate::ros::msg_schema::MsgSchema;

    /// The field layout of every type of a schema, as (type name, [(field, element, array)]).
    fn layout(s: &MsgSchema) -> Vec<(String, Vec<String>)> {
        s.types
            .iter()
            .map(|t| {
                let mut f: Vec<String> = t.fields.iter().map(|f| format!("{} {:?} {:?}", f.name, f.ty, f.array)).collect();
                f.sort();
                (t.name.clone(), f)
            })
            .collect()
    }

    #[test]
    fn bundled_definitions_parse_as_the_recordings_write_them() {
        let name = "sensor_msgs/msg/Imu";
        let ours = MsgSchema::parse(name, &full_definition(name, &[]).unwrap()).unwrap();
        let theirs = MsgSchema::parse(name, IMU_MSG).unwrap();
        assert_eq!(ours.root().fields.len(), theirs.root().fields.len());
        let (mut a, mut b) = (layout(&ours), layout(&theirs));
        a.sort();
        b.sort();
        assert_eq!(a, b);
        for name in ["geometry_msgs/msg/PoseWithCovarianceStamped", "diagnostic_msgs/msg/DiagnosticArray"] {
            MsgSchema::parse(name, &full_definition(name, &[]).unwrap()).unwrap();
        }
    }

    #[test]
    fn a_workspace_type_is_found_with_its_dependencies() {
        let dir = std::env::temp_dir().join(format!("uwbimu-ros-types-{}", std::process::id()));
        let msg = dir.join("my_uwb").join("msg");
        std::fs::create_dir_all(&msg).unwrap();
        std::fs::write(msg.join("Ranges.msg"), "std_msgs/Header header\nAnchorRange[] ranges # one per anchor\n").unwrap();
        std::fs::write(msg.join("AnchorRange.msg"), "uint16 id\nfloat32 range\ngeometry_msgs/Point pos\n").unwrap();
        let text = full_definition("my_uwb/msg/Ranges", std::slice::from_ref(&dir)).unwrap();
        let schema = MsgSchema::parse("my_uwb/msg/Ranges", &text).unwrap();
        let names: Vec<&str> = schema.types.iter().map(|t| t.name.as_str()).collect();
        assert!(names.contains(&"my_uwb/AnchorRange") && names.contains(&"geometry_msgs/Point"), "{names:?}");
        let missing = full_definition("my_uwb/msg/Other", std::slice::from_ref(&dir)).unwrap_err().to_string();
        assert!(missing.contains("no definition of `my_uwb/Other`") && missing.contains("live.msg_paths"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn dds_names_follow_ros2() {
        assert_eq!(dds_type_name("sensor_msgs/msg/Imu"), "sensor_msgs::msg::dds_::Imu_");
        assert_eq!(dds_type_name("nav_msgs/Odometry"), "nav_msgs::msg::dds_::Odometry_");
        assert_eq!(dds_topic_name("/uwb/ranges"), "rt/uwb/ranges");
    }
}
