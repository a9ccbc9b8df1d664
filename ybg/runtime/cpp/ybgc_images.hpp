// Camera images in ybgc's C++ runtime (docs/ros2-native.md, "Images"): a
// YARP port of images to a ROS 2 sensor_msgs/Image (with its CameraInfo), and
// a ROS 2 sensor_msgs/Image topic to a YARP port of images. A frame is a
// yarp::sig::FlexImage of any pixel type (ybgc::Frame), and goes through the
// bridge as a Bottle does: the same check of the port that sent it, the
// same freshness, trigger, queue, totals and /diagnostics (a frame of
// another pixel type than declared is refused: counted, said once). What a frame
// costs: read from YARP into the port's image and swapped out of it (no
// copy), its rows copied once into the message's data (without YARP's row
// padding); read from ROS 2, its rows copied once into a packed image that
// the YARP port sends as it is (no copy). ybgc writes this file and
// ybgc_images.cpp beside a module that reads or writes images (always one
// with ROS 2: ybgc_ros2.hpp), which links YARP_sig.
#ifndef YBGC_IMAGES_HPP
#define YBGC_IMAGES_HPP

#include "ybgc_ros2.hpp"  // ybgc:runtime-import

#include <sensor_msgs/msg/camera_info.h>
#include <sensor_msgs/msg/image.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace ybgc {

/// Prints a mux's frame: "[<mux>] 321x241 rgb8" (no frame: "[<mux>] no frame").
void printMux(const char* name, const Frame& frame);

namespace images {

// --- pixel types ------------------------------------------------------------------------

/// The YARP pixel code of a ROS encoding (docs/ros2-native.md: rgb8 is
/// VOCAB_PIXEL_RGB, bgr8 BGR, rgba8 RGBA, bgra8 BGRA, mono8 and 8UC1 MONO,
/// mono16 and 16UC1 MONO16, 32FC1 MONO_FLOAT); 0 for an encoding YARP has
/// no pixel type for.
int pixelCode(const std::string& encoding);

/// The ROS encoding of a YARP pixel code, the first of the table (MONO16:
/// mono16); nullptr for a pixel type ROS has no encoding for here.
const char* encodingOf(int code);

/// Bytes per pixel of a pixel code of the table (0 for another).
std::size_t pixelSize(int code);

/// A pixel code as YARP names it (its four characters: "rgb", "mo16").
std::string codeName(int code);

/// What a frame is, for the messages of a module: "a frame 321x241 rgb8", "no frame".
std::string describe(const Frame& frame);

/// Copies `rows` rows of `bytes` bytes each, from rows `srcStep` bytes apart
/// to rows `dstStep` bytes apart (one memcpy when neither has padding).
void copyRows(unsigned char* dst, std::size_t dstStep, const unsigned char* src, std::size_t srcStep,
              std::size_t bytes, std::size_t rows);

// --- a YARP port of images to ROS 2 -----------------------------------------------------

/// Why a frame read from YARP is not one an input of `encoding` takes ("":
/// it is), as the Python runtime says it: a frame of no pixels, or of
/// another pixel type than the encoding's (mono16 and 16UC1 are both YARP's
/// MONO16). Such a frame is refused (ybgc::refuseFrame): counted as refused,
/// said once, never used.
std::string refusal(const yarp::sig::FlexImage& frame, const char* encoding);

/// The port of a YARP camera image input (a ybgc::FramePorts): a
/// BufferedPort of FlexImage, which reads a frame of any pixel type as it
/// came (its own row padding, never converted); each frame is swapped out
/// of the port's image (no copy) and handed to the input with its envelope.
std::unique_ptr<FramePort> framePort(Input& input);

/// Fills a sensor_msgs/Image from a frame: `height`, `width`, `encoding`
/// (the declared one), `is_bigendian` 0 (YARP's pixels are little endian),
/// `step` = width * pixel size and `data`, the rows copied without YARP's
/// padding (the message's data is sized again when the frame's size
/// changes). False when there is no frame or its data cannot be allocated.
bool setImage(sensor_msgs__msg__Image& msg, const Frame& frame, const char* encoding);

/// A CameraInfo of the calibration's size (its `width` and `height`, when
/// both are set) for a frame of `width` x `height`: when the sizes differ,
/// k[0], k[2], p[0], p[2] are scaled by width / its width, k[4], k[5],
/// p[5], p[6] by height / its height, and the frame's size is published.
void fitCameraInfo(sensor_msgs__msg__CameraInfo& info, std::uint32_t width, std::uint32_t height);

/// The CameraInfo published beside each image: its topic, and the module's
/// filler of the fields the config gives (its header is the image's).
struct CameraInfoSpec
{
    const char* topic;
    void (*fill)(sensor_msgs__msg__CameraInfo& info);
};

/// The publisher of a ROS 2 image (ybgc::ros2::Publisher) and, with a
/// CameraInfoSpec, of its CameraInfo: right after each image, on the same
/// node with the same QoS (and the qos_overrides of its own topic), the
/// image's header, fitted to the frame (fitCameraInfo).
class ImagePublisher : public ros2::Publisher
{
public:
    ImagePublisher(const ros2::Ros2Spec& spec, const ros2::MessageType& type, ros2::FillMessage fill,
                   const CameraInfoSpec* cameraInfo, std::vector<std::string> rosArgs);
    ~ImagePublisher() override;

    bool open() override;
    std::string describe() const override;
    bool publish(const Inputs& in, const Context& ctx, std::string& failure) override;
    void close() override;
    void ros2Events(std::vector<Totals::Ros2Endpoint>& out) const override;

private:
    struct Rcl;
    void closeInfo();
    const ros2::Ros2Spec& spec_;
    const CameraInfoSpec* cameraInfo_;
    std::unique_ptr<Rcl> rcl_;
};

/// Runs a bridge that publishes a ROS 2 image read from YARP (`fill` fills
/// the sensor_msgs/Image: setImage), with its CameraInfo (`cameraInfo`,
/// nullptr for none), and reads ROS 2 topics too (`topics`, nullptr for
/// none), until SIGINT or SIGTERM; the exit status.
int runImagePublisher(const BridgeSpec& spec, const ros2::Ros2Spec& ros2, const ros2::MessageType& type,
                      const CameraInfoSpec* cameraInfo, const ros2::Topics* topics, int argc, char* argv[],
                      ros2::FillMessage fill);

/// The same, `fill` the module's builder of the sensor_msgs/Image.
template <class Msg>
int run(const BridgeSpec& spec, const ros2::Ros2Spec& ros2, const ros2::MessageType& type,
        const CameraInfoSpec* cameraInfo, const ros2::Topics* topics, int argc, char* argv[],
        bool (*fill)(const Inputs&, const Context&, Msg&, std::string&))
{
    static_assert(std::is_same_v<Msg, sensor_msgs__msg__Image>, "the message of a camera image is its Image");
    return runImagePublisher(spec, ros2, type, cameraInfo, topics, argc, argv, ros2::filling(fill));
}

// --- a ROS 2 image topic to a YARP port of images ---------------------------------------------

/// Reads a sensor_msgs/Image into a frame (the reader of a ROS 2 camera
/// input, for ybgc::ros2::topic): the pixel type of its encoding, its rows
/// copied one by one (ROS's step may be padded) into an image of packed rows
/// (quantum 1); its envelope is its header.stamp (ybgc::ros2::topic). An
/// encoding YARP has no pixel type for, big-endian 16- or 32-bit pixels, no
/// pixels, a step shorter than a row or data shorter than step * height: no
/// frame, and `out.refused` says why (the input refuses it: refuseFrame).
void read(const sensor_msgs__msg__Image& msg, Reading& out);

/// The YARP port of images of a bridge (`[output] image = <mux>`): for each
/// message, the frame of input `input` (BridgeSpec::inputs), written as it
/// is (its pixels not copied: the prepared image points at them, and the
/// frame is kept until the port has sent it), its envelope the frame's (its
/// header.stamp), else the clock. `make` runs the module's gather and
/// compute (its Bottle is not written); never waits for a slow reader.
std::unique_ptr<MessageSink> imageOutput(const OutputSpec& spec, std::size_t input, MakeMessage make);

/// Runs a bridge whose output is a YARP port of the images of input `input`,
/// read from the ROS 2 `topics`, until SIGINT or SIGTERM; the exit status.
int run(const BridgeSpec& spec, std::size_t input, const ros2::Topics& topics, int argc, char* argv[],
        MakeMessage make);

}  // namespace images
}  // namespace ybgc

#endif  // YBGC_IMAGES_HPP
