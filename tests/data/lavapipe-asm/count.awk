# Independent count of one function's dump (the function's lines on stdin), for
# tests/data/lavapipe-asm/README.md: instructions, vector spills, stack stores, vector reloads,
# folded reloads, mask spills/reloads, calls, table calls, host calls, stack bytes.
BEGIN { FS = "\t" }
/^ +[0-9a-f]+:\t/ {
  ins++; m = $2; ops = $3; line[ins] = $0; mn[ins] = m; op[ins] = ops
  # stack slots read at a fixed offset: source operands of non-lea instructions
  if (m !~ /^lea/) { n = split(ops, a, ", "); for (i = 1; i < n; i++) { x = a[i]; sub(/ .*/, "", x); if (x ~ /^-?[0-9]*\(%r[sb]p\)$/) rd[x] = 1 } }
}
END {
  for (k = 1; k <= ins; k++) {
    m = mn[k]; n = split(op[k], a, ", "); f = a[1]; l = a[n]; sub(/ .*/, "", f); sub(/ .*/, "", l)
    slot_l = (l ~ /^-?[0-9]*\(%r[sb]p\)$/); slot_f = (f ~ /^-?[0-9]*\(%r[sb]p\)$/)
    if (m ~ /^call/) { calls++; if (f ~ /^\*.*\(/) tc++; else if (f ~ /^\*%/ && mn[k-1] ~ /^movabs/ && op[k-1] ~ (substr(f, 2) "$")) hc++; continue }
    if (m == "subq" && l == "%rsp") { v = substr(f, 2) + 0; if (v > sb) sb = v; continue }
    if (n < 2) continue
    if (m ~ /^v?mov(aps|ups|apd|upd|dqa|dqu)(8|16|32|64)?$/) {
      if (f ~ /^%[xyz]mm/ && slot_l) { if (l in rd) sp++; else ss++ }
      else if (slot_f && l ~ /^%[xyz]mm/) rl++
    } else if (m ~ /^kmov[bwdq]$/) {
      if (f ~ /^%k[0-9]+$/ && slot_l) ks++; else if (slot_f && l ~ /^%k[0-9]+$/) kr++
    } else if (m !~ /^v?mov(ss|sd|d|q|lps|hps|lpd|hpd)$/ && m !~ /^lea/) {
      src = 0; for (i = 1; i < n; i++) { x = a[i]; sub(/ .*/, "", x); if (x ~ /^-?[0-9]*\(%r[sb]p\)$/) src = 1 }
      if (src && op[k] ~ /%[xyz]mm|%k[0-9]/) fr++
    }
  }
  printf "instructions=%d vector_spills=%d stack_stores=%d vector_reloads=%d folded_reloads=%d mask_spills=%d mask_reloads=%d calls=%d table_calls=%d host_calls=%d stack_bytes=%d\n", ins, sp, ss, rl, fr, ks, kr, calls, tc, hc, sb
}
