// shoal_channel_emulator: thin main; the app is emulator_app.
#include "channel_emulator/emulator_app.h"

int main(int argc, char** argv) { return shoal::EmulatorMain(argc, argv); }
