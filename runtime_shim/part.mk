# runtime_shim/: plcrt, the soft-PLC runtime (C core library + thin executable, libmodbus),
# and plcharness, the Python package that builds ST programs into it for pytest.
PY_PACKAGES += runtime_shim/harness

RT_BUILD    := $(BUILD)/runtime_shim
RT_SRC      := runtime_shim/src
RT_CORE     := plcrt_core plcrt_image plcrt_config plcrt_master plcrt_slave
RT_HEADERS  := runtime_shim/include/plcrt.h $(RT_SRC)/plcrt_internal.h
RT_CFLAGS   := -std=gnu11 -Wall -Wextra -O2 -g -fPIC -Iruntime_shim/include
RT_LIBS     := -lmodbus -lpthread -lm

$(RT_BUILD)/%.o: $(RT_SRC)/%.c $(RT_HEADERS)
	@mkdir -p $(@D)
	$(CC) $(RT_CFLAGS) -c $< -o $@

$(RT_BUILD)/libplcrt.a: $(foreach f,$(RT_CORE),$(RT_BUILD)/$(f).o)
	ar rcs $@ $^

BUILD_TARGETS += $(RT_BUILD)/libplcrt.a

PYTEST_DEPS += $(RT_BUILD)/libplcrt.a
