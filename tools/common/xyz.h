// What the external baseline programs (tools/ear, tools/mls) share: the command line
// "INPUT.xyz OUTPUT.xyz --ratio R" of `pumeta eval --method external`, reading "x y z" lines
// with one-line errors naming the file, and writing the output through a temporary file so
// that a failure leaves none. Header-only: each program links only its own library.
#pragma once

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace pumeta::tools {

using Xyz = std::array<double, 3>;

struct Arguments {
    std::string input, output;
    long ratio = 0;
};

/// "<program>: error: <message>" on stderr; returns `code` (2: bad input, 1: a failure).
inline int fail(const char* program, int code, const std::string& message) {
    std::fprintf(stderr, "%s: error: %s\n", program, message.c_str());
    return code;
}

/// The arguments, or the message saying what is wrong with them.
inline std::optional<std::string> parse_arguments(int argc, char** argv, const char* program,
                                                  Arguments& args) {
    if (argc != 5 || std::string(argv[3]) != "--ratio")
        return std::string("usage: ") + program + " INPUT.xyz OUTPUT.xyz --ratio R";
    args.input = argv[1];
    args.output = argv[2];
    args.ratio = std::strtol(argv[4], nullptr, 10);
    if (args.ratio < 2) return std::string("--ratio must be an integer >= 2, found ") + argv[4];
    return std::nullopt;
}

/// The finite points of the "x y z" lines of `path` (blank lines skipped), at least
/// `least` of them for `method`, or the message naming the file and, where one is wrong,
/// its line.
inline std::optional<std::string> read_xyz(const std::string& path, std::vector<Xyz>& points,
                                           std::size_t least, const char* method) {
    std::ifstream in(path);
    if (!in) return path + ": cannot open";
    std::string line;
    for (long number = 1; std::getline(in, line); ++number) {
        std::istringstream fields(line);
        double x, y, z;
        if (!(fields >> x >> y >> z)) {
            if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
            return path + ": line " + std::to_string(number) + ": expected x y z";
        }
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
            return path + ": line " + std::to_string(number) + ": not a finite point";
        points.push_back({x, y, z});
    }
    if (points.size() < least)
        return path + ": " + std::to_string(points.size()) + " points; " + method +
               " needs at least " + std::to_string(least);
    return std::nullopt;
}

/// The arguments and the input's points (at least `least`, for `method`): 0, else the exit
/// code after saying what is wrong.
inline int load_input(int argc, char** argv, const char* program, std::size_t least,
                      const char* method, Arguments& args, std::vector<Xyz>& points) {
    if (auto error = parse_arguments(argc, argv, program, args)) return fail(program, 2, *error);
    if (auto error = read_xyz(args.input, points, least, method)) return fail(program, 2, *error);
    return 0;
}

/// Writes `points` to `path` through `path`.tmp, or returns the message.
inline std::optional<std::string> write_xyz(const std::string& path,
                                            const std::vector<Xyz>& points) {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp);
        out.precision(9);
        for (const Xyz& p : points) out << p[0] << " " << p[1] << " " << p[2] << "\n";
        out.close();  // so that an error of the final flush is seen too
        if (!out) {
            std::remove(tmp.c_str());
            return path + ": cannot write";
        }
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        std::remove(tmp.c_str());
        return path + ": cannot write";
    }
    return std::nullopt;
}

}  // namespace pumeta::tools
