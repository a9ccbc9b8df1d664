// Camera images in ybgc's C++ runtime (ybgc_images.hpp): the table of pixel
// types, the port of a YARP camera image input, a frame into a
// sensor_msgs/Image and its CameraInfo, a sensor_msgs/Image into a frame, and
// the YARP port of images.
#include "ybgc_images.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/rcl.h>

#include <yarp/os/BufferedPort.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/ConnectionWriter.h>
#include <yarp/os/Portable.h>
#include <yarp/os/Stamp.h>
#include <yarp/sig/Image.h>

#include <chrono>
#include <cstring>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace ybgc {

void printMux(const char* name, const Frame& frame)
{
    std::string text = "no frame";
    if (frame != nullptr) {
        const char* encoding = images::encodingOf(frame->getPixelCode());
        text = std::to_string(frame->width()) + "x" + std::to_string(frame->height()) + " "
            + (encoding != nullptr ? encoding : images::codeName(frame->getPixelCode()));
    }
    printLines(std::string("[") + name + "] " + text + "\n");
}

namespace images {

// --- pixel types ------------------------------------------------------------------------

namespace {

struct Pixel
{
    const char* encoding;
    int code;
    std::size_t size;     // bytes per pixel
    std::size_t channel;  // bytes per channel (byte order matters above 1)
};

/// ROS encoding <-> YARP pixel type: the first entry of a code gives its encoding.
const Pixel kPixels[] = {
    {"rgb8", VOCAB_PIXEL_RGB, 3, 1},
    {"bgr8", VOCAB_PIXEL_BGR, 3, 1},
    {"rgba8", VOCAB_PIXEL_RGBA, 4, 1},
    {"bgra8", VOCAB_PIXEL_BGRA, 4, 1},
    {"mono8", VOCAB_PIXEL_MONO, 1, 1},
    {"8UC1", VOCAB_PIXEL_MONO, 1, 1},
    {"mono16", VOCAB_PIXEL_MONO16, 2, 2},
    {"16UC1", VOCAB_PIXEL_MONO16, 2, 2},
    {"32FC1", VOCAB_PIXEL_MONO_FLOAT, 4, 4},
};

const Pixel* byCode(int code)
{
    for (const Pixel& p : kPixels) {
        if (p.code == code) {
            return &p;
        }
    }
    return nullptr;
}

}  // namespace

int pixelCode(const std::string& encoding)
{
    for (const Pixel& p : kPixels) {
        if (encoding == p.encoding) {
            return p.code;
        }
    }
    return 0;
}

const char* encodingOf(int code)
{
    const Pixel* p = byCode(code);
    return p != nullptr ? p->encoding : nullptr;
}

std::size_t pixelSize(int code)
{
    const Pixel* p = byCode(code);
    return p != nullptr ? p->size : 0;
}

std::string codeName(int code)
{
    std::string out;
    bool printable = true;
    for (int rest = code; rest > 0 && out.size() < 4; rest >>= 8) {
        const char c = static_cast<char>(rest & 0xff);
        printable = printable && c >= ' ' && c <= '~';
        out += c;
    }
    return !out.empty() && printable ? out : std::to_string(code);
}

std::string describe(const Frame& frame)
{
    if (frame == nullptr) {
        return "no frame";
    }
    const char* encoding = encodingOf(frame->getPixelCode());
    return "a frame " + std::to_string(frame->width()) + "x" + std::to_string(frame->height()) + " "
        + (encoding != nullptr ? encoding : codeName(frame->getPixelCode()));
}

void copyRows(unsigned char* dst, std::size_t dstStep, const unsigned char* src, std::size_t srcStep,
              std::size_t bytes, std::size_t rows)
{
    if (rows == 0 || bytes == 0) {
        return;
    }
    if (dstStep == bytes && srcStep == bytes) {
        std::memcpy(dst, src, bytes * rows);
        return;
    }
    for (std::size_t y = 0; y < rows; ++y) {
        std::memcpy(dst + y * dstStep, src + y * srcStep, bytes);
    }
}

namespace {

/// The images of the frames of one port, used again once no message holds
/// them (a frame read into an image of its size allocates nothing): a
/// frame is a shared_ptr whose deleter gives its image back.
class FramePool : public std::enable_shared_from_this<FramePool>
{
public:
    /// An image of the pool (or a new one), as a frame to fill.
    std::shared_ptr<yarp::sig::FlexImage> take()
    {
        std::unique_ptr<yarp::sig::FlexImage> image;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (!free_.empty()) {
                image = std::move(free_.back());
                free_.pop_back();
            }
        }
        if (image == nullptr) {
            image = std::make_unique<yarp::sig::FlexImage>();
        }
        std::weak_ptr<FramePool> pool = shared_from_this();
        return {image.release(), [pool](yarp::sig::FlexImage* used) {
                    if (const std::shared_ptr<FramePool> p = pool.lock()) {
                        p->give(used);
                    } else {
                        delete used;
                    }
                }};
    }

private:
    /// Images kept for the next frames: those a message holds, in the
    /// queues, and in the port's hands, are the others.
    static constexpr std::size_t kKept = 4;

    void give(yarp::sig::FlexImage* image)
    {
        std::unique_ptr<yarp::sig::FlexImage> owned(image);
        std::lock_guard<std::mutex> lock(mutex_);
        if (free_.size() < kKept) {
            free_.push_back(std::move(owned));
        }
    }

    std::mutex mutex_;
    std::vector<std::unique_ptr<yarp::sig::FlexImage>> free_;
};

}  // namespace

// --- a YARP port of images to ROS 2 -----------------------------------------------------

std::string refusal(const yarp::sig::FlexImage& frame, const char* encoding)
{
    const int code = frame.getPixelCode();
    if (code == VOCAB_PIXEL_INVALID || frame.width() == 0 || frame.height() == 0) {
        return "a frame of no pixels";
    }
    const int want = pixelCode(encoding);
    if (code == want) {
        return "";
    }
    return "pixel type " + codeName(code) + ", not " + codeName(want) + ": the declared " + encoding;
}

namespace {

/// A frame with the name of the port that sent it, read as it came: the
/// sender's pixel type and row padding (a FlexImage of quantum 0 takes the
/// sender's quantum, so YARP reads the pixels straight into it, never
/// converting them), and of no pixel type until it is read (a frame of no
/// pixels leaves it so).
class SourcedFrame : public yarp::os::Portable
{
public:
    bool read(yarp::os::ConnectionReader& connection) override
    {
        source = connection.getRemoteContact().getName();
        problem.clear();
        image.setQuantum(0);
        image.setPixelCode(VOCAB_PIXEL_INVALID);
        try {
            return image.read(connection);
        } catch (const std::out_of_range&) {
            // YARP knows no size for the sender's pixel code (it set the code before failing)
            problem = "pixel type " + codeName(image.getPixelCode()) + ", which YARP does not know";
            return true;
        }
    }

    bool write(yarp::os::ConnectionWriter& connection) const override { return image.write(connection); }

    yarp::sig::FlexImage image;
    std::string source;
    std::string problem;  // not empty: the frame could not be read
};

/// The port of a YARP camera image input: each frame's image is swapped
/// with one of the pool's, the port reading the next frames into that one.
class FramePortOf : public FramePort, public yarp::os::TypedReaderCallback<SourcedFrame>
{
public:
    explicit FramePortOf(Input& input) : input_(input), pool_(std::make_shared<FramePool>()) {}

    bool open(const std::string& name, bool strict) override
    {
        port_.setStrict(strict);
        port_.useCallback(*this);
        return port_.open(name);
    }

    void close() override
    {
        port_.disableCallback();
        port_.close();
    }

    yarp::os::Contactable& port() override { return port_; }

    using yarp::os::TypedReaderCallback<SourcedFrame>::onRead;

    void onRead(SourcedFrame& in) override
    {
        yarp::os::Stamp stamp;
        const bool hasEnvelope = port_.getEnvelope(stamp) && stamp.isValid();
        std::string why = !in.problem.empty() ? in.problem : refusal(in.image, input_.spec.image);
        Frame frame;
        if (why.empty()) {
            std::shared_ptr<yarp::sig::FlexImage> image = pool_->take();
            image->swap(in.image);  // no copy: the port reads the next frame into the pool's image
            frame = std::move(image);
        }
        input_.onFrame(in.source, frame, hasEnvelope, hasEnvelope ? stamp.getTime() : 0.0, port_.getPendingReads(),
                       why);
    }

private:
    Input& input_;
    std::shared_ptr<FramePool> pool_;
    yarp::os::BufferedPort<SourcedFrame> port_;
};

}  // namespace

std::unique_ptr<FramePort> framePort(Input& input)
{
    return std::make_unique<FramePortOf>(input);
}

bool setImage(sensor_msgs__msg__Image& msg, const Frame& frame, const char* encoding)
{
    if (frame == nullptr) {
        return false;
    }
    const std::size_t width = frame->width();
    const std::size_t height = frame->height();
    const std::size_t row = width * frame->getPixelSize();
    if (!ros2::resize(msg.data, row * height)) {
        return false;
    }
    copyRows(msg.data.data, row, frame->getRawImage(), frame->getRowSize(), row, height);
    msg.height = static_cast<std::uint32_t>(height);
    msg.width = static_cast<std::uint32_t>(width);
    ros2::setString(msg.encoding, encoding);
    msg.is_bigendian = 0;
    msg.step = static_cast<std::uint32_t>(row);
    return true;
}

void fitCameraInfo(sensor_msgs__msg__CameraInfo& info, std::uint32_t width, std::uint32_t height)
{
    if (info.width == 0 || info.height == 0 || (info.width == width && info.height == height)) {
        return;
    }
    const double sx = static_cast<double>(width) / static_cast<double>(info.width);
    const double sy = static_cast<double>(height) / static_cast<double>(info.height);
    info.k[0] *= sx;
    info.k[2] *= sx;
    info.k[4] *= sy;
    info.k[5] *= sy;
    info.p[0] *= sx;
    info.p[2] *= sx;
    info.p[5] *= sy;
    info.p[6] *= sy;
    info.width = width;
    info.height = height;
}

namespace {

std::string rclError()
{
    std::string text = rcl_get_error_string().str;
    rcl_reset_error();
    return text;
}

}  // namespace

struct ImagePublisher::Rcl
{
    rcl_publisher_t publisher = rcl_get_zero_initialized_publisher();
    bool publisherOk = false;
    sensor_msgs__msg__CameraInfo* info = nullptr;
    std::string topic;  // as remapped
    bool reportedError = false;
    std::unique_ptr<ros2::PeerEvents> peers;  // of its publisher
};

ImagePublisher::ImagePublisher(const ros2::Ros2Spec& spec, const ros2::MessageType& type, ros2::FillMessage fill,
                               const CameraInfoSpec* cameraInfo, std::vector<std::string> rosArgs) :
        ros2::Publisher(spec, type, std::move(fill), std::move(rosArgs)), spec_(spec), cameraInfo_(cameraInfo),
        rcl_(std::make_unique<Rcl>())
{
    if (cameraInfo_ != nullptr) {
        rcl_->topic = cameraInfo_->topic;
        rcl_->peers = std::make_unique<ros2::PeerEvents>("publisher", cameraInfo_->topic,
                                                         "sensor_msgs/msg/CameraInfo");
    }
}

ImagePublisher::~ImagePublisher()
{
    closeInfo();
}

bool ImagePublisher::open()
{
    if (!ros2::Publisher::open()) {
        return false;
    }
    if (cameraInfo_ == nullptr) {
        return true;
    }
    Rcl& r = *rcl_;
    rcl_publisher_options_t options = rcl_publisher_get_default_options();
    options.qos = ros2::configQos(spec_);
    std::string error;
    if (!node().qos(cameraInfo_->topic, "publisher", options.qos, r.topic, error)) {
        say(std::string("cannot publish sensor_msgs/msg/CameraInfo on ") + cameraInfo_->topic + ": " + error);
        return false;
    }
    if (rcl_publisher_init(&r.publisher, node().node(), ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, CameraInfo),
                           cameraInfo_->topic, &options) != RCL_RET_OK) {
        say(std::string("cannot publish sensor_msgs/msg/CameraInfo on ") + cameraInfo_->topic + ": " + rclError());
        return false;
    }
    r.publisherOk = true;
    r.peers->watch(node(), &r.publisher);
    r.info = sensor_msgs__msg__CameraInfo__create();
    if (r.info == nullptr) {
        say("cannot allocate a sensor_msgs/msg/CameraInfo");
        return false;
    }
    return true;
}

std::string ImagePublisher::describe() const
{
    const std::string image = ros2::Publisher::describe();
    return cameraInfo_ == nullptr ? image : image + ", with its sensor_msgs/msg/CameraInfo on " + rcl_->topic;
}

bool ImagePublisher::publish(const Inputs& in, const Context& ctx, std::string& failure)
{
    if (!ros2::Publisher::publish(in, ctx, failure)) {
        return false;
    }
    Rcl& r = *rcl_;
    if (cameraInfo_ == nullptr || r.info == nullptr) {
        return true;
    }
    const auto& image = *static_cast<const sensor_msgs__msg__Image*>(message());
    sensor_msgs__msg__CameraInfo& info = *r.info;
    cameraInfo_->fill(info);
    info.header.stamp = image.header.stamp;
    ros2::setString(info.header.frame_id, std::string(image.header.frame_id.data, image.header.frame_id.size));
    fitCameraInfo(info, image.width, image.height);
    if (rcl_publish(&r.publisher, &info, nullptr) != RCL_RET_OK) {
        if (!r.reportedError) {
            r.reportedError = true;
            say("cannot publish on " + r.topic + ": " + rclError() + "; further errors are not said");
        } else {
            rcl_reset_error();
        }
    }
    return true;
}

void ImagePublisher::closeInfo()
{
    Rcl& r = *rcl_;
    if (r.info != nullptr) {
        sensor_msgs__msg__CameraInfo__destroy(r.info);
        r.info = nullptr;
    }
    if (r.peers != nullptr) {
        r.peers->stop();
    }
    if (r.publisherOk) {
        if (rcl_publisher_fini(&r.publisher, node().node()) != RCL_RET_OK) {
            rcl_reset_error();
        }
        r.publisherOk = false;
    }
}

void ImagePublisher::ros2Events(std::vector<Totals::Ros2Endpoint>& out) const
{
    ros2::Publisher::ros2Events(out);
    if (rcl_->peers != nullptr) {
        out.push_back(rcl_->peers->counts());
    }
}

void ImagePublisher::close()
{
    closeInfo();  // before the node closes
    ros2::Publisher::close();
}

// --- a ROS 2 image topic to a YARP port of images ---------------------------------------------

void read(const sensor_msgs__msg__Image& msg, Reading& out)
{
    // one pool for every ROS 2 camera input of the module (their reader is one thread)
    static const std::shared_ptr<FramePool> pool = std::make_shared<FramePool>();
    const std::string encoding(msg.encoding.data != nullptr ? msg.encoding.data : "", msg.encoding.size);
    const Pixel* pixel = byCode(pixelCode(encoding));
    if (pixel == nullptr) {
        out.refused = "encoding " + (encoding.empty() ? std::string("''") : encoding)
            + ", which YARP has no pixel type for";
        return;
    }
    if (msg.is_bigendian != 0 && pixel->channel > 1) {
        out.refused = "big-endian " + encoding + " pixels (YARP's are little-endian)";
        return;
    }
    if (msg.width == 0 || msg.height == 0) {
        out.refused = "no pixels (" + std::to_string(msg.width) + "x" + std::to_string(msg.height) + ")";
        return;
    }
    const std::size_t row = static_cast<std::size_t>(msg.width) * pixel->size;
    if (msg.step < row) {
        out.refused = "step " + std::to_string(msg.step) + ", shorter than a row of " + std::to_string(msg.width)
            + " " + encoding + " pixels";
        return;
    }
    const std::size_t need = static_cast<std::size_t>(msg.step) * msg.height;
    if (msg.data.size < need) {
        out.refused = std::to_string(msg.data.size) + " bytes of data, fewer than step x height = "
            + std::to_string(need);
        return;
    }
    std::shared_ptr<yarp::sig::FlexImage> image = pool->take();
    image->setPixelCode(pixel->code);
    image->setQuantum(1);  // packed rows: before resize, which lays them out
    image->resize(msg.width, msg.height);
    copyRows(image->getRawImage(), image->getRowSize(), msg.data.data, msg.step, row, msg.height);
    out.frame = std::move(image);
}

namespace {

/// The YARP port of images: each frame goes out as it is, the prepared
/// image pointing at its pixels (yarp::sig::Image::setExternal), the frame
/// kept with that image until the port prepares the image again, once it
/// is no longer being sent.
class ImageOutput : public MessageSink
{
public:
    ImageOutput(const OutputSpec& spec, std::size_t input, MakeMessage make) :
            spec_(spec), input_(input), make_(std::move(make))
    {
    }

    bool open() override
    {
        port_.setWriteOnly();
        if (!port_.open(spec_.port)) {
            return false;
        }
        registered_ = port_.getName();
        return true;
    }

    std::string describe() const override { return std::string("camera images on ") + spec_.port; }

    std::string registered() const override { return registered_; }

    yarp::os::Contact where() const override { return port_.where(); }

    std::int64_t nowNs() override
    {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(
                   std::chrono::system_clock::now().time_since_epoch()).count();
    }

    bool publish(const Inputs& in, const Context& ctx, std::string& failure) override
    {
        bottle_.clear();
        if (!make_(in, ctx, bottle_, failure)) {  // the module's gather and compute
            failure = tooShort(failure);
            return false;
        }
        const Latest& latest = in[input_];
        const Frame& frame = latest.frame;
        if (frame == nullptr) {
            failure = "no frame";
            return false;
        }
        yarp::sig::FlexImage& out = port_.prepare();
        keep(out, frame);
        out.setPixelCode(frame->getPixelCode());
        out.setQuantum(frame->getQuantum());
        out.setExternal(frame->getRawImage(), frame->width(), frame->height());
        yarp::os::Stamp stamp(static_cast<int>(ctx.counter % 2147483647u),
                              latest.hasEnvelope ? latest.envelope : ctx.seconds);
        port_.setEnvelope(stamp);
        writePatiently(port_, patient_);
        return true;
    }

    void close() override
    {
        port_.interrupt();
        port_.close();
        kept_.clear();
    }

private:
    /// `image` is prepared again: it is no longer sent, and holds `frame` now.
    void keep(const yarp::sig::FlexImage& image, const Frame& frame)
    {
        for (auto& [prepared, held] : kept_) {
            if (prepared == &image) {
                held = frame;
                return;
            }
        }
        kept_.emplace_back(&image, frame);
    }

    const OutputSpec& spec_;
    const std::size_t input_;
    MakeMessage make_;
    yarp::os::Bottle bottle_;
    std::vector<std::pair<const yarp::sig::FlexImage*, Frame>> kept_;  // outlives the port's images
    yarp::os::BufferedPort<yarp::sig::FlexImage> port_;
    std::string registered_;
    bool patient_ = true;
};

}  // namespace

std::unique_ptr<MessageSink> imageOutput(const OutputSpec& spec, std::size_t input, MakeMessage make)
{
    return std::make_unique<ImageOutput>(spec, input, std::move(make));
}

int run(const BridgeSpec& spec, std::size_t input, const ros2::Topics& topics, int argc, char* argv[],
        MakeMessage make)
{
    RosCommandLine line(argc, argv, spec.module, topics.node);
    if (line.status != 0) {
        return line.status;
    }
    ros2::Subscriptions subscriptions(topics, std::move(line.rosArgs));
    const std::unique_ptr<MessageSink> output = imageOutput(spec.output, input, std::move(make));
    return ybgc::run(spec, line.argc(), line.argv(), *output, &subscriptions, &framePort);
}

int runImagePublisher(const BridgeSpec& spec, const ros2::Ros2Spec& ros2, const ros2::MessageType& type,
                      const CameraInfoSpec* cameraInfo, const ros2::Topics* topics, int argc, char* argv[],
                      ros2::FillMessage fill)
{
    RosCommandLine line(argc, argv, spec.module, ros2.node);
    if (line.status != 0) {
        return line.status;
    }
    ImagePublisher publisher(ros2, type, std::move(fill), cameraInfo, std::move(line.rosArgs));
    std::unique_ptr<ros2::Subscriptions> subscriptions;
    if (topics != nullptr) {
        subscriptions = std::make_unique<ros2::Subscriptions>(*topics, std::vector<std::string>{}, &publisher);
    }
    return ybgc::run(spec, line.argc(), line.argv(), publisher, subscriptions.get(), &framePort);
}

}  // namespace images
}  // namespace ybgc
