%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE Cell
  ! An example cell for twin compensate --rapid (docs/compensation.md): two robtargets with
  ! tool0, three with a gun in a work object turned 30 degrees, two joint targets.
  PERS tooldata gun := [TRUE,[[0,0,120],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];
  TASK PERS wobjdata table := [FALSE,TRUE,"",[[450,-100,50],[0.965925826,0,0,0.258819045]],[[0,0,0],[1,0,0,0]]];
  CONST robtarget p10 := [[5.86,21.552,746.796],[0.350605,0.092618,-0.227864,0.903646],[-2,-1,-2,5],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p20 := [[156.321,-85.361,592.002],[-0.645165,0.217314,0.270062,0.680884],[1,-1,2,4],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p30 := [[-658.664,78.151,299.132],[0.115882,0.959591,-0.113817,-0.229787],[-2,-1,-4,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p40 := [[-641.578,496.321,327.699],[0.159334,0.856944,-0.026896,-0.489424],[1,0,-2,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p50 := [[-509.189,332.954,655.73],[-0.349992,0.206331,0.912337,0.050731],[-2,-1,-2,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST jointtarget j1 := [[90.403,-70.064,-4.073,-47.52,-59.253,-84.825],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST jointtarget j2 := [[-118.035,45.873,-25.646,-90.262,107.384,-181.42],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

  PROC main()
    ConfJ \On;
    ConfL \On;
    MoveAbsJ j1, v500, fine, tool0;
    MoveL p10, v200, fine, tool0;
    MoveL p20, v200, fine, tool0;
    MoveL p30, v200, fine, gun\WObj:=table;
    MoveL p40, v200, fine, gun\WObj:=table;
    MoveL p50, v200, fine, gun\WObj:=table;
    MoveAbsJ j2, v500, fine, tool0;
  ENDPROC
ENDMODULE
