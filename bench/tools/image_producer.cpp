// Benchmark camera: writes stamped images on a YARP port, as a YARP grabber
// does (a BufferedPort of images, one envelope a frame).
//
//   bench_image_producer --port /bench/cam:o --width 640 --height 480 --pixel rgb8|32FC1
//
// Commands on stdin, one a line; each answers with one line on stdout,
// starting with "@" (YARP prints its own messages there too):
//   wait N TIMEOUT   wait until the port has at least N output connections
//                    -> "ok <connections>" or "timeout <connections>"
//   run COUNT RATE   COUNT frames at RATE Hz with absolute deadlines
//                    -> "done <first seq> <frames> <late frames> <elapsed s>"
//   quit             close the port and exit
//
// Frame s: the pixels of a fixed pattern (rgb8: bytes, 32FC1: depths in
// metres), rows packed (quantum 1: YARP adds no padding), except its first
// 16 bytes, the sequence number s (uint64) and t (double), and the last 8
// bytes of its last row, s again. t is CLOCK_MONOTONIC in seconds taken just
// before the write; the envelope is (s, t): a bridge copies it into the
// sensor_msgs/Image's header.stamp, from which the sink measures the latency.
// Writes are strict (a frame is never dropped by the producer: when the
// reader is slow, the producer falls behind and counts late frames).

#include <time.h>

#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>

#include <yarp/os/BufferedPort.h>
#include <yarp/os/Network.h>
#include <yarp/os/Stamp.h>
#include <yarp/sig/Image.h>

namespace {

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void sleepUntil(const timespec& t)
{
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) != 0) {
    }
}

void addNs(timespec& t, long long ns)
{
    long long total = static_cast<long long>(t.tv_nsec) + ns;
    t.tv_sec += static_cast<time_t>(total / 1000000000LL);
    t.tv_nsec = static_cast<long>(total % 1000000000LL);
}

bool before(const timespec& a, const timespec& b)
{
    return a.tv_sec < b.tv_sec || (a.tv_sec == b.tv_sec && a.tv_nsec < b.tv_nsec);
}

void answer(const std::string& line)
{
    std::fputs(("@" + line + "\n").c_str(), stdout);
    std::fflush(stdout);
}

/// The pattern of a frame's pixels (every frame: only its stamps differ).
void fill(yarp::sig::FlexImage& img, bool depth)
{
    const std::size_t w = img.width();
    for (std::size_t y = 0; y < img.height(); ++y) {
        unsigned char* row = img.getRow(y);
        if (depth) {
            auto* d = reinterpret_cast<float*>(row);
            for (std::size_t x = 0; x < w; ++x) {
                d[x] = 0.5f + static_cast<float>((x + y) % 1000) * 0.005f;
            }
        } else {
            for (std::size_t i = 0; i < w * 3; ++i) {
                row[i] = static_cast<unsigned char>((i * 7 + y * 13) & 0xff);
            }
        }
    }
}

}  // namespace

int main(int argc, char* argv[])
{
    std::string name = "/bench/cam:o";
    std::size_t width = 640;
    std::size_t height = 480;
    std::string pixel = "rgb8";
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        if (key == "--port") {
            name = argv[i + 1];
        } else if (key == "--width") {
            width = std::strtoul(argv[i + 1], nullptr, 10);
        } else if (key == "--height") {
            height = std::strtoul(argv[i + 1], nullptr, 10);
        } else if (key == "--pixel") {
            pixel = argv[i + 1];
        }
    }
    const bool depth = pixel == "32FC1";
    if ((!depth && pixel != "rgb8") || width < 8 || height < 2) {
        std::fprintf(stderr, "usage: bench_image_producer --port P --width W (>= 8) --height H (>= 2) "
                             "--pixel rgb8|32FC1\n");
        return 2;
    }
    std::signal(SIGPIPE, SIG_IGN);  // a peer that goes away must not kill this process
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "bench_image_producer: no YARP name server\n");
        return 1;
    }
    yarp::os::BufferedPort<yarp::sig::FlexImage> port;
    port.setWriteOnly();
    if (!port.open(name)) {
        std::fprintf(stderr, "bench_image_producer: cannot open %s\n", name.c_str());
        return 1;
    }
    answer("ready");

    std::uint64_t seq = 0;
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "wait") {
            int want = 1;
            double timeout = 10.0;
            in >> want >> timeout;
            const double end = monotonicNow() + timeout;
            int have = 0;
            while ((have = port.getOutputCount()) < want && monotonicNow() < end) {
                timespec t{0, 20 * 1000000L};
                nanosleep(&t, nullptr);
            }
            answer((have >= want ? "ok " : "timeout ") + std::to_string(have));
        } else if (cmd == "run") {
            long long count = 0;
            double rate = 30.0;
            in >> count >> rate;
            const long long period = static_cast<long long>(1e9 / rate + 0.5);
            const std::uint64_t first = seq + 1;
            long long late = 0;
            const double t0 = monotonicNow();
            timespec next{};
            clock_gettime(CLOCK_MONOTONIC, &next);
            for (long long k = 0; k < count; ++k) {
                ++seq;
                yarp::sig::FlexImage& img = port.prepare();
                const int code = depth ? VOCAB_PIXEL_MONO_FLOAT : VOCAB_PIXEL_RGB;
                if (img.getPixelCode() != code || img.width() != width || img.height() != height
                    || img.getQuantum() != 1) {
                    img.setPixelCode(code);
                    img.setQuantum(1);
                    img.resize(width, height);
                    fill(img, depth);
                }
                const double t = monotonicNow();
                unsigned char* first_row = img.getRawImage();
                std::memcpy(first_row, &seq, 8);
                std::memcpy(first_row + 8, &t, 8);
                unsigned char* last = img.getRow(height - 1) + width * img.getPixelSize() - 8;
                std::memcpy(last, &seq, 8);
                yarp::os::Stamp stamp(static_cast<int>(seq % 2147483647u), t);
                port.setEnvelope(stamp);
                port.writeStrict();
                addNs(next, period);
                timespec now{};
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (before(next, now)) {
                    ++late;  // behind schedule: go on at once (no sleep)
                } else {
                    sleepUntil(next);
                }
            }
            std::ostringstream out;
            out.precision(9);
            out << "done " << first << " " << count << " " << late << " " << (monotonicNow() - t0);
            answer(out.str());
        } else if (cmd == "quit") {
            break;
        } else if (!cmd.empty()) {
            answer("error unknown command " + cmd);
        }
    }
    port.waitForWrite();
    port.close();
    return 0;
}
