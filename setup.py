"""The C twins of the rigs' hot loops (see plant_emulators/engine.py); everything else about
the package is in pyproject.toml. (Extensions are declared here because pyproject.toml's
``ext-modules`` table is still experimental in setuptools.)

The flags keep IEEE double arithmetic exactly as written: no contraction into FMA, no
reassociation, sin and cos not merged into sincos. That is what lets a twin give the Python
model's floats bit for bit.
"""

from setuptools import Extension, setup

EXACT_FLOATS = ["-std=c11", "-O2", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin-sin",
                "-fno-builtin-cos", "-Wall", "-Wextra", "-Werror"]
SHARED_HEADERS = ["plant_emulators/native/normal_block.h",
                  "plant_emulators/native/py_normal_block.h", "plant_emulators/native/py_glue.h"]

setup(ext_modules=[
    Extension("plant_emulators.fertilizer._plant_native",
              sources=["plant_emulators/fertilizer/native/plant_core.c",
                       "plant_emulators/fertilizer/native/plant_module.c"],
              depends=["plant_emulators/fertilizer/native/plant_core.h", *SHARED_HEADERS],
              extra_compile_args=EXACT_FLOATS),
    Extension("plant_emulators.fertilizer._flow_sensor_native",
              sources=["plant_emulators/fertilizer/native/flow_sensor_core.c",
                       "plant_emulators/fertilizer/native/flow_sensor_module.c"],
              depends=["plant_emulators/fertilizer/native/flow_sensor_core.h",
                       *SHARED_HEADERS],
              extra_compile_args=EXACT_FLOATS),
    Extension("plant_emulators.fertilizer._ground_speed_native",
              sources=["plant_emulators/fertilizer/native/ground_speed_core.c",
                       "plant_emulators/fertilizer/native/ground_speed_module.c"],
              depends=["plant_emulators/fertilizer/native/ground_speed_core.h",
                       *SHARED_HEADERS],
              extra_compile_args=EXACT_FLOATS),
    Extension("plant_emulators.sowing_depth._drive_cycle_native",
              sources=["plant_emulators/sowing_depth/native/drive_cycle_core.c",
                       "plant_emulators/sowing_depth/native/drive_cycle_module.c"],
              depends=["plant_emulators/sowing_depth/native/drive_cycle_core.h"],
              extra_compile_args=EXACT_FLOATS),
])
