MODULE line_arc
  ! written by accura convert from line_arc.xml: targets in the work object (mm, quaternion w,x,y,z); confdata the source does not give is 0 and configuration monitoring is off (ConfJ\Off, ConfL\Off: the controller takes the configuration nearest the current one)
  ! accura_tool1: the load (1 kg at [0,0,1] mm) is a placeholder, not the tool's: set its mass and centre of gravity (LoadIdentify) before running
  PERS tooldata accura_tool1 := [TRUE,[[0.0000,0.0000,150.0000],[1.000000000,0.000000000,0.000000000,0.000000000]],[1,[0,0,1],[1,0,0,0],0,0,0]];
  PERS wobjdata accura_wobj1 := [FALSE,TRUE,"",[[300.0000,-150.0000,100.0000],[0.707106781,0.000000000,0.000000000,0.707106781]],[[0,0,0],[1,0,0,0]]];
  CONST robtarget P1 := [[40.0000,-60.0000,120.0000],[0.000000000,1.000000000,0.000000000,0.000000000],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget P2 := [[40.0000,-60.0000,20.0000],[0.000000000,1.000000000,0.000000000,0.000000000],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget P3 := [[40.0000,60.0000,20.0000],[0.000000000,1.000000000,0.000000000,0.000000000],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  PROC main()
    ConfJ\Off;
    ConfL\Off;
    ! written by hand: a motion-only program for the XML -> RAPID conversion (tests/golden/rapid/line_arc.mod)
    MoveAbsJ [[0.00000,0.00000,0.00000,0.00000,30.00000,0.00000],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v1000, fine, accura_tool1\WObj:=accura_wobj1;
    MoveJ P1, v1000, fine, accura_tool1\WObj:=accura_wobj1;
    MoveL P2, [250.0000,500,5000,1000], z5, accura_tool1\WObj:=accura_wobj1;
    MoveC [[100.0000,0.0000,20.0000],[0.000000000,1.000000000,0.000000000,0.000000000],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], P3, v20, [FALSE,1.5000,2.2500,2.2500,0.2250,2.2500,0.2250], accura_tool1\WObj:=accura_wobj1;
    MoveL P1, v100, fine, accura_tool1\WObj:=accura_wobj1;
  ENDPROC
ENDMODULE
