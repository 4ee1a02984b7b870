// pumeta convert IN -o OUT: between any readable and any writable format.
#include "pumeta/cli/commands.h"

namespace pumeta::cli {

void add_convert_command(CLI::App& app) {
    struct Args {
        std::string input, output;
        ReadOptions read;
        WriteOptions write;
        bool ascii = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand("convert", "convert a cloud or mesh between formats");
    command->add_option("input", args->input, "input file")->required();
    command->add_option("-o,--output", args->output, "output file (format by extension)")
        ->required();
    command->add_option("--output-format", args->write.format, "output format override");
    command->add_flag("--ascii", args->ascii, "ascii instead of binary (PLY, PCD)");
    add_read_options(*command, args->read);
    command->callback([args] {
        args->write.binary = !args->ascii;
        Geometry geometry = read_geometry(args->input, args->read);
        write_geometry(args->output, geometry, args->write);
    });
}

}  // namespace pumeta::cli
