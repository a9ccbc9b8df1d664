// Benchmark image consumer: records the receive time of every image arriving
// on a YARP port, with the sequence number and send time the producer put in
// it (bench/tools/image_producer.cpp): the YARP hop of camera images alone.
//
//   bench_image_consumer --port /bench/img_sink:i --source /bench/cam:o
//                        --width 640 --height 480 --pixel rgb8|32FC1
//
// The port is a plain yarp::os::Port whose reader runs in the connection's
// own thread: an image is recorded as soon as it is read off the socket (into
// one FlexImage, reused). The latency is measured from the envelope's time
// (the producer's send time); a frame whose size, pixel type, stamps in the
// pixels (the first 16 bytes and the last 8) or envelope do not match is
// counted as bad.
//
// Commands on stdin (one answer line each on stdout, starting with "@"):
//   count           -> "count <records> <bad>"
//   reset           -> "reset" (forget the records)
//   dump PATH       -> "dumped <records>": raw float64, 11 per record (the
//                      layout of bench/tools/consumer.cpp): recv, 1, bad, seq, t,
//                      then zeros
//   quit
// "connected" is printed once the source is connected (retried until it exists).

#include <time.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Bytes.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/Network.h>
#include <yarp/os/Port.h>
#include <yarp/os/PortReader.h>
#include <yarp/sig/Image.h>

namespace {

constexpr int kFields = 11;

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void answer(const std::string& line)
{
    std::fputs(("@" + line + "\n").c_str(), stdout);
    std::fflush(stdout);
}

class Recorder : public yarp::os::PortReader
{
public:
    std::size_t width = 640;
    std::size_t height = 480;
    int code = VOCAB_PIXEL_RGB;

    std::mutex mutex;
    std::vector<double> data;
    long long count = 0;
    long long bad = 0;
    yarp::sig::FlexImage image;

    bool read(yarp::os::ConnectionReader& connection) override
    {
        image.setQuantum(0);  // the sender's
        if (!image.read(connection)) {
            return false;
        }
        const double recv = monotonicNow();
        const yarp::os::Bytes env = connection.readEnvelope();
        double envTime = NAN;
        if (env.length() > 0) {
            yarp::os::Bottle b;
            b.fromString(std::string(env.get(), env.length()));
            if (b.size() >= 2) {
                envTime = b.get(1).asFloat64();
            }
        }
        std::uint64_t seq = 0;
        std::uint64_t seqEnd = 0;
        double t = NAN;
        bool isBad = image.getPixelCode() != code || image.width() != width || image.height() != height;
        if (!isBad) {
            const unsigned char* raw = image.getRawImage();
            std::memcpy(&seq, raw, 8);
            std::memcpy(&t, raw + 8, 8);
            std::memcpy(&seqEnd, image.getRow(height - 1) + width * image.getPixelSize() - 8, 8);
            // the envelope's time, written as text by YARP: to the microsecond at least
            isBad = seqEnd != seq || !(std::fabs(envTime - t) < 1e-6);
        }
        const double rec[kFields] = {recv, 1, isBad ? 1.0 : 0.0, static_cast<double>(seq),
                                     std::isnan(envTime) ? t : envTime, 0, 0, 0, 0, 0, 0};
        std::lock_guard<std::mutex> lock(mutex);
        ++count;
        if (isBad) {
            ++bad;
        }
        data.insert(data.end(), rec, rec + kFields);
        return true;
    }
};

}  // namespace

int main(int argc, char* argv[])
{
    std::string portName = "/bench/img_sink:i";
    std::string source;
    std::string pixel = "rgb8";
    Recorder recorder;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        if (key == "--port") {
            portName = argv[i + 1];
        } else if (key == "--source") {
            source = argv[i + 1];
        } else if (key == "--width") {
            recorder.width = std::strtoul(argv[i + 1], nullptr, 10);
        } else if (key == "--height") {
            recorder.height = std::strtoul(argv[i + 1], nullptr, 10);
        } else if (key == "--pixel") {
            pixel = argv[i + 1];
        } else {
            std::fprintf(stderr, "bench_image_consumer: unknown argument %s\n", key.c_str());
            return 2;
        }
    }
    recorder.code = pixel == "32FC1" ? VOCAB_PIXEL_MONO_FLOAT : VOCAB_PIXEL_RGB;
    recorder.data.reserve(static_cast<std::size_t>(kFields) * 100000);
    std::signal(SIGPIPE, SIG_IGN);
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "bench_image_consumer: no YARP name server\n");
        return 1;
    }
    yarp::os::Port port;
    port.setReader(recorder);
    if (!port.open(portName)) {
        std::fprintf(stderr, "bench_image_consumer: cannot open %s\n", portName.c_str());
        return 1;
    }
    answer("ready");

    std::atomic<bool> quitting{false};
    std::thread connector([&] {
        while (!source.empty() && !quitting) {
            if (yarp::os::Network::exists(source, true)
                && yarp::os::Network::connect(source, port.getName(), "tcp", true)) {
                answer("connected");
                return;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
    });

    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "count") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            answer("count " + std::to_string(recorder.count) + " " + std::to_string(recorder.bad));
        } else if (cmd == "reset") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            recorder.data.clear();
            recorder.count = 0;
            recorder.bad = 0;
            answer("reset");
        } else if (cmd == "dump") {
            std::string path;
            in >> path;
            std::vector<double> copy;
            {
                std::lock_guard<std::mutex> lock(recorder.mutex);
                copy = recorder.data;
            }
            FILE* f = std::fopen(path.c_str(), "wb");
            if (f == nullptr) {
                answer("error cannot write " + path);
                continue;
            }
            std::fwrite(copy.data(), sizeof(double), copy.size(), f);
            std::fclose(f);
            answer("dumped " + std::to_string(copy.size() / kFields));
        } else if (cmd == "quit") {
            break;
        } else if (!cmd.empty()) {
            answer("error unknown command " + cmd);
        }
    }
    quitting = true;
    connector.join();
    port.interrupt();
    port.close();
    return 0;
}
