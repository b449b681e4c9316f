"""The LGF-style S7 status word the SCL export adds to a block (stc.scl_out): which status
outputs a block gets and the SCL region that keeps each one up to date (st_lib/CONVENTIONS.md
"status-word"; docs/wiring-s7.md)."""

# LGF-style status words (Siemens "Library of General Functions" / PLCopen convention: 16#0000
# done, 16#7000 idle, 16#7001 first call of a job, 16#7002 job running, 16#8xxx error)
STATUS_NAME = "status"
STATUS_PREV = "statusBusyBefore"
# the status word of an error: 16#8000 + the library's base + the error's position in its
# enum; the library is told by the type of eErrorId (st_lib/CONVENTIONS.md "error-range":
# the core's E_MIP_Error 16#8001.., the chain's E_MIP_ChainError 16#8101..)
STATUS_ERROR_BASE = {"E_MIP_CHAINERROR": 0x8100}
STATUS_ERROR_DEFAULT = 0x8000
# the sides of a combined block (its output infix, the prefix of its status word's name)
STATUS_SIDES = (("Send", "send"), ("Recv", "recv"))


def sides(blocks, local_names):
    """[(output infix, status name, name of its "busy before" local)]: one for a block with
    xBusy, xError, eErrorId outputs, one per side for a combined block (xSendBusy ...,
    xRecvBusy ...); none on a name clash. `blocks`: the POU's declaration blocks;
    `local_names`: the upper-case names it declares."""
    outs = {n for b in blocks if b.kind == "VAR_OUTPUT" for d in b.decls for n, _ in d.names}
    found = [("", STATUS_NAME, STATUS_PREV)]
    if not {"XBUSY", "XERROR", "EERRORID"} <= outs:
        found = [(infix, pre + "Status", pre + "StatusBusyBefore") for infix, pre in STATUS_SIDES]
    return [s for s in found
            if {f"X{s[0]}BUSY".upper(), f"X{s[0]}ERROR".upper(), f"E{s[0]}ERRORID".upper()} <= outs
            and s[1].upper() not in local_names and s[2].upper() not in local_names]


def error_base(blocks, infix=""):
    """The status word's base for an error: by the type of the block's e<infix>ErrorId."""
    want = f"E{infix}ERRORID".upper()
    for b in blocks:
        if b.kind != "VAR_OUTPUT":
            continue
        for d in b.decls:
            if any(n == want for n, _ in d.names):
                t = getattr(d.type, "name", "") or ""
                return STATUS_ERROR_BASE.get(t.upper(), STATUS_ERROR_DEFAULT)
    return STATUS_ERROR_DEFAULT


def region(blocks, local_names, infix="", status=STATUS_NAME, prev=STATUS_PREV):
    """The SCL lines of the REGION that sets `status` at the end of the block's body."""
    i = infix
    has_done = f"X{i}DONE".upper() in local_names
    r = ["", f"    REGION LGF {status}",
         f"        // generated: {status} follows x{i}Busy, x{i}Error and e{i}ErrorId (Siemens "
         "LGF convention, docs/wiring-s7.md)",
         f"        IF #x{i}Error THEN",
         f"            #{status} := WORD#16#{error_base(blocks, i):04X} OR INT_TO_WORD(#e{i}ErrorId);",
         f"        ELSIF #x{i}Busy THEN",
         f"            IF #{prev} THEN",
         f"                #{status} := WORD#16#7002;",
         "            ELSE",
         f"                #{status} := WORD#16#7001;",
         "            END_IF;"]
    if has_done:
        r += [f"        ELSIF #x{i}Done THEN", f"            #{status} := WORD#16#0;"]
    r += ["        ELSE", f"            #{status} := WORD#16#7000;", "        END_IF;",
          f"        #{prev} := #x{i}Busy;", "    END_REGION"]
    return r
